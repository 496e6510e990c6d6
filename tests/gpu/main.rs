//! The tests that render: every node and the facade on a wgpu adapter (lavapipe where there is
//! no GPU), each image against the f64 reference, at the driver's precision and at WGSL's worst
//! case. One test binary (one link step); each file beside this one is a topic. What the tiers share
//! (the device, metric lines, scenes) is `volshadow_harness`.
//! `cargo test --test gpu` runs them alone; `cargo test --test gpu -- soft` one topic.

mod airlight_table;
mod cascades;
mod composite;
mod crossing_depths;
mod directional;
mod exact;
mod facade;
mod frame;
mod hardening;
mod headless;
mod iss_spot;
mod iss_table;
mod large_occluders;
mod light_placement;
mod occluder_texel;
mod shadows;
mod soft;
mod soft_grid;
mod surface_shadow;
mod textured_spot;
mod upsample;
mod validation;
mod warm_up;
