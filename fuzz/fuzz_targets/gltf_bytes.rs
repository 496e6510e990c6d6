//! The glTF / GLB loader on arbitrary bytes.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = volshadow::gltf::load_slice_with(data, &common::options());
});
