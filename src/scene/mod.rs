//! Scene types shared by the GPU nodes and the f64 reference: medium, phase function, lights,
//! camera. Every constructor validates its input and returns [`crate::Error`] on bad values.

mod camera;
mod light;
mod light_texture;
mod medium;
mod mesh;
pub mod shapes;

pub use camera::Camera;
pub use light::{DirectionalLight, Light, PointLight, SpotLight};
pub use light_texture::{LightTexture, TextureChannels};
pub use medium::{Medium, PhaseFunction};
pub(crate) use mesh::{check_object_transform, TransformProblem};
pub use mesh::{Edge, Mesh, MeshSummary};
