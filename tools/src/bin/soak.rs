//! The soak: the facade for many frames with everything animated ([`volshadow_tools::soak`]).
//!
//! ```text
//! cargo run --release -p volshadow_tools --bin soak -- [--frames 2000] [--help]
//! ```

fn main() {
    volshadow_tools::soak::main();
}
