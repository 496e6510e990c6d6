//! # volshadow
//!
//! Volumetric shadows — light shafts, and the dark shafts that occluders cut through fog,
//! haze and smoke — for homogeneous single-scattering media, as render-graph nodes that record
//! into the caller's own `wgpu` device and command encoder.
//!
//! The airlight (in-scattered light) is evaluated in closed form through a per-frame table
//! built on the GPU from the stable form of Sun et al.'s model (see `DESIGN.md` §2 in the
//! repository), so it stays finite and accurate from optical depth 1e-4 to 100, looking straight
//! into the light or with the light behind the eye.
//!
//! Objects are split by lifetime: a shared [`gpu::Cache`] of pipelines and layouts, and
//! per-view nodes ([`nodes`]) that own their textures. Each node has `new`, `prepare`
//! (validates, resizes, uploads what changed) and `encode` (records into a
//! `&mut wgpu::CommandEncoder`; nodes never submit).
//!
//! [`reference`](mod@reference) is an independent f64 integrator of the same model, the ground truth the tests
//! compare every GPU image with.
#![warn(missing_docs)]

pub mod error;
mod facade;
#[cfg(feature = "gltf")]
pub mod gltf;
pub mod gpu;
pub mod load;
pub mod nodes;
pub mod plan;
pub mod reference;
pub mod scene;
pub mod scene_file;

pub use error::{Error, Result};
pub use facade::{Frame, FrameLight, Settings, VolumetricShadows};
pub use gpu::headless::HeadlessGpu;
pub use gpu::Cache;
pub use gpu::{Occluder, OccluderMesh};
pub use load::{Limit, LoadOptions};
pub use plan::Plan;
pub use scene::{Camera, Light, Medium, PhaseFunction, PointLight, SpotLight};

pub use glam;
pub use wgpu;
