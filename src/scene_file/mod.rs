//! JSON scene files: camera, lights, medium, objects, output size and method in one file, so
//! any image can be reproduced from it.
//!
//! [`SceneDescription::load`] reads, validates and builds everything: the scene types
//! ([`Camera`], [`Light`], [`Medium`], [`Mesh`], [`LightTexture`]) are constructed, so a
//! loaded scene is ready to render. Every problem is an [`Error::SceneFile`] ([`SceneFileError`]) naming the file,
//! the field (a path such as `lights[1].cone_angle_degrees`) and what is wrong; no input
//! panics.
//!
//! # Format
//!
//! ```json
//! {
//!   "name": "sphere",
//!   "description": "optional free text",
//!   "size": [512, 512],
//!   "camera": { "eye": [0, 2, 8], "target": [0, 1, 0], "up": [0, 1, 0],
//!               "fov_y_degrees": 45, "near": 0.1, "far": null, "reversed_z": false },
//!   "lights": [
//!     { "type": "point", "position": [0, 6, 0], "intensity": 40 },
//!     { "type": "spot", "position": [0, 6, 0], "direction": [0, -1, 0],
//!       "cone_angle_degrees": 50, "intensity": [40, 38, 35],
//!       "texture": { "stained_glass": { "size": 256, "cells": 8, "seed": 7 } } }
//!   ],
//!   "medium": { "sigma_s": 0.04, "sigma_a": [0.01, 0.01, 0.01],
//!               "phase": { "henyey_greenstein": 0.3 } },
//!   "objects": [
//!     { "name": "ground", "shape": { "type": "plane", "center": [0, 0, 0], "half_size": [20, 20] },
//!       "casts_shadow": false, "albedo": 0.5 },
//!     { "name": "ball", "shape": { "type": "sphere", "center": [0, 0, 0], "radius": 1 },
//!       "transform": { "translate": [0, 2, 0], "rotate_degrees": [0, 30, 0], "scale": [1.5, 1, 1] } }
//!   ],
//!   "method": { "type": "hybrid", "steps": 64, "scale": 2, "upsample": "depth_aware_3x3",
//!               "bisections": 0 }
//! }
//! ```
//!
//! Unknown keys are errors everywhere; `null` counts as absent.
//!
//! Loading is bounded by [`LoadOptions`] (lights, texels, triangles, placed meshes, bytes), and
//! files the scene names must lie in its folder unless [`LoadOptions::allow_outside`] is set.
//!
//! * `name` (required string), `description` (optional string).
//! * `size`: `[width, height]`, each 1..=8192; default `[512, 512]`.
//! * `camera` (required): `eye`, `target` (required points), `up` (default `[0, 1, 0]`, not
//!   parallel to the view direction), `fov_y_degrees` (required, in (0, 180)), `near`
//!   (required, > 0), `far` (absent or `null`: infinite; else > `near`), `reversed_z` (default
//!   `false`). The aspect ratio is `width / height`. The view is
//!   [`glam::camera::rh::view::look_at_mat4`], the projection
//!   `glam::camera::rh::proj::directx::{perspective, perspective_infinite,
//!   perspective_infinite_reverse}` (reversed Z with a finite far plane swaps near and far).
//! * `lights` (required, at least one), each with `"type"`:
//!   * `"point"`: `position`, `intensity` (RGB or one number; >= 0, not all zero).
//!   * `"spot"`: `position`, `direction` (non-zero), `cone_angle_degrees` (apex angle, in
//!     (0, 179]: see [`SpotLight::MAX_CONE_ANGLE`](crate::SpotLight::MAX_CONE_ANGLE)), `intensity`, optional `texture`, one of
//!     `{"checkerboard": {"size", "cells", "a", "b"}}` (size 1..=4096, cells 1..=size, colours
//!     RGB >= 0), `{"stained_glass": {"size", "cells", "seed"}}` (see [`stained_glass`]; size
//!     1..=4096, cells 1..=size) or `{"file": "window.png"}` (feature `image`; relative to the
//!     scene file's folder, and inside it: see [`crate::load`]); optional `texture_up`, the
//!     texture frame's up hint (see [`SpotLight::with_texture_up`](crate::SpotLight::with_texture_up)).
//!   * both: optional `radius` (finite, >= 0, default 0): the light is a sphere of that radius
//!     and casts soft shadows (see [`PointLight`](crate::PointLight#radius-soft-shadows)).
//! * `medium` (required): `sigma_s` (RGB or one number, >= 0; required unless the phase is
//!   `hoffman_preetham`, which sets it and forbids it), `sigma_a` (default 0), `phase` (default
//!   `"isotropic"`): `"isotropic"`, `"rayleigh"`, `"mie_hazy"`, `"mie_murky"`,
//!   `{"henyey_greenstein": g}` or `{"hoffman_preetham": {"rayleigh": [..], "mie": [..], "g": g}}`,
//!   with `|g| < 1`.
//! * `objects` (default none), each: `name` (default `"<type>_<index>"`), `shape` (required),
//!   `transform` (default identity), `casts_shadow` (default `true`), `albedo` (RGB or one
//!   number in [0, 1], default 0.8). Shapes, by `"type"` (lengths in [1e-6, 1e6], points within
//!   ±1e6, segment counts 3..=1024):
//!   * `"sphere"`: `center`, `radius`, `segments` (default 32), `rings` (default 16, 2..=1024).
//!   * `"box"`: `center`, `half_extents`.
//!   * `"plane"`: `center`, `half_size` `[x, z]`: a rectangle in the XZ plane facing +Y (open).
//!   * `"torus"`: `center`, `major_radius`, `minor_radius` (< major, >= 1e-4 major), axis +Y,
//!     `major_segments` (default 48), `minor_segments` (default 16).
//!   * `"spring"`: `center`, `coil_radius`, `wire_radius` (>= 1e-4 of the coil radius and
//!     height), `turns` (in [0.01, 1000]), `height`, axis +Y, `segments_per_turn` (default 32,
//!     3..=256, turns × segments_per_turn at most 16384), `wire_segments` (default 12, 3..=64).
//!   * `"cylinder"`: `center`, `radius`, `half_height`, `segments` (default 32): an open tube
//!     along +Y.
//!   * `"fence"`: `posts` (1..=1024), `spacing` (centre to centre, along X), `post_half_extents`,
//!     `center` (default origin; the centre of the row of posts), `rail` (default `false`: two
//!     horizontal rails at 30% and 75% of the post height, slightly narrower than the posts);
//!     all boxes merged into one mesh.
//!   * `"gltf"`: `path` (relative to the scene file's folder and inside it, see
//!     [`crate::load`]; feature `gltf`): every mesh of the
//!     file (each triangle primitive of each node that places a mesh, as `volshadow::gltf::load` gives them) becomes
//!     one object named `"<name>/<mesh name>"` (`"<name>/<index>:<mesh name>"` when several
//!     primitives share the mesh name, `"<name>/<index>"` without one), with transform
//!     `transform × (the mesh's node transform)`.
//!
//!   `transform` is either `{"translate": [x, y, z], "rotate_degrees": [x, y, z],
//!   "scale": s or [x, y, z]}` (each optional; the matrix is `T · Rz · Ry · Rx · S`: scale,
//!   then rotate about X, then Y, then Z, then translate; scales > 0) or `{"matrix": [16
//!   numbers]}`, column-major, affine with a positive determinant (mirroring would flip the
//!   triangles' winding).
//! * `method` (default hybrid): `"reference"`, `"hybrid"`, `"brute_force"` (each with default
//!   settings), or an object with `"type"` and, for `"brute_force"`, `steps` (1..=4096, default
//!   64), `bisections` (0..=16, default 0), `texture_steps` (hybrid, textured spots: steps
//!   before and after the extents, 1..=4096, default 32), `scale` (the divisor of the output size for the
//!   scattering passes: 1, 2 or 4, default 1); for `"hybrid"` the same plus `upsample`:
//!   `"bilinear"`, `"depth_aware_3x3"` (default) or `{"separable": {"taps" (odd, 3..=31),
//!   "sigma_spatial" (> 0), "sigma_depth" (> 0)}}`.

mod glass;
mod parse;
mod spec;

use std::path::Path;

use glam::{DVec3, Mat4, Vec3};

pub use crate::error::SceneFileError;
use crate::error::{Error, Result};
use crate::load::{Budget, LoadOptions};
use crate::nodes::{MarchMethod, MarchSettings, Scale, UpsampleFilter};
use crate::reference::{Occluder, TriangleMesh};
use crate::scene::{Camera, Light, LightTexture, Medium, Mesh};

pub use glass::stained_glass;

/// A scene read from a JSON file: everything validated and constructed (see the
/// [module docs](self) for the format).
#[derive(Debug, Clone)]
pub struct SceneDescription {
    /// The scene's name.
    pub name: String,
    /// Optional free text (what the scene shows, derived numbers).
    pub description: Option<String>,
    /// Output width and height in pixels (1..=8192 each).
    pub size: (u32, u32),
    /// The camera, with the aspect ratio of `size`.
    pub camera: Camera,
    /// The lights, at least one.
    pub lights: Vec<SceneLight>,
    /// The medium.
    pub medium: Medium,
    /// Occluders and receivers.
    pub objects: Vec<SceneObject>,
    /// How to render it.
    pub method: Method,
}

/// A light and, for a spot light, its optional projected texture.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneLight {
    /// The light.
    pub light: Light,
    /// The spot light's texture (`None` for point lights and untextured spots).
    pub texture: Option<LightTexture>,
}

/// One object: a mesh in its own space placed in the world by `transform`.
#[derive(Debug, Clone)]
pub struct SceneObject {
    /// The object's name (from the file, or `"<shape type>_<index>"`).
    pub name: String,
    /// The mesh, in object space (a shape's `center` is already applied).
    pub mesh: Mesh,
    /// Object → world (affine, positive determinant).
    pub transform: Mat4,
    /// Whether it casts shadows (is an occluder); receivers such as the ground set `false`.
    pub casts_shadow: bool,
    /// Diffuse reflectance, linear RGB in [0, 1].
    pub albedo: Vec3,
}

/// How a scene is rendered.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Method {
    /// The f64 reference integrator ([`crate::reference`]).
    Reference,
    /// The GPU march over the whole ray ([`MarchMethod::BruteForce`]).
    BruteForce {
        /// Steps per ray (1..=4096).
        steps: u32,
        /// Bisection steps per lit/shadow transition (0..=16).
        bisections: u32,
        /// Resolution of the scattering passes.
        scale: Scale,
    },
    /// The GPU hybrid: analytic outside the shadow volumes, marched inside
    /// ([`MarchMethod::Hybrid`]).
    Hybrid {
        /// Steps per marched interval (1..=4096).
        steps: u32,
        /// Resolution of the scattering passes.
        scale: Scale,
        /// How low-resolution scattering is upsampled (used when `scale` is not full).
        upsample: UpsampleFilter,
        /// Bisection steps per lit/shadow transition (0..=16).
        bisections: u32,
        /// Textured spot lights: steps before and after the extents (1..=4096, default 32).
        texture_steps: u32,
    },
    /// The GPU exact method: closed form between the sorted shadow-volume crossings of each
    /// ray ([`MarchMethod::Exact`]).
    Exact {
        /// Steps per marched interval of a pixel whose crossing list overflowed (1..=4096).
        steps: u32,
        /// Resolution of the scattering passes.
        scale: Scale,
        /// How low-resolution scattering is upsampled (used when `scale` is not full).
        upsample: UpsampleFilter,
        /// Bisection steps per lit/shadow transition of an overflowed pixel (0..=16).
        bisections: u32,
        /// Textured spot lights: steps along the cone (1..=4096, default 32).
        texture_steps: u32,
        /// Crossing list entries per pixel.
        crossings: u32,
    },
    /// The textbook march in distance ([`MarchMethod::Textbook`]): a baseline.
    Textbook {
        /// Steps per ray (1..=4096).
        steps: u32,
        /// Resolution of the scattering passes.
        scale: Scale,
    },
}

impl Default for Method {
    /// [`Method::exact_default`].
    fn default() -> Self {
        Method::exact_default()
    }
}

impl Method {
    /// `Hybrid` with the defaults of [`MarchSettings`] at full resolution.
    pub fn hybrid_default() -> Self {
        let m = MarchSettings::default();
        Method::Hybrid {
            steps: m.steps,
            scale: Scale::Full,
            upsample: UpsampleFilter::DepthAware3x3,
            bisections: m.bisections,
            texture_steps: m.texture_steps,
        }
    }

    /// `Exact` with the defaults of [`MarchSettings`] at full resolution (no bisection): the
    /// default method.
    pub fn exact_default() -> Self {
        let m = MarchSettings::default();
        Method::Exact {
            steps: m.steps,
            scale: Scale::Full,
            upsample: UpsampleFilter::DepthAware3x3,
            bisections: m.bisections,
            texture_steps: m.texture_steps,
            crossings: m.crossings,
        }
    }

    /// The march settings of a GPU method; `None` for [`Method::Reference`].
    pub fn march_settings(&self) -> Option<MarchSettings> {
        match *self {
            Method::Reference => None,
            Method::BruteForce {
                steps,
                bisections,
                scale,
                ..
            } => Some(MarchSettings {
                method: MarchMethod::BruteForce,
                steps,
                bisections,
                scale,
                ..MarchSettings::default()
            }),
            Method::Hybrid {
                steps,
                bisections,
                scale,
                texture_steps,
                ..
            } => Some(MarchSettings {
                method: MarchMethod::Hybrid,
                steps,
                bisections,
                scale,
                texture_steps,
                ..MarchSettings::default()
            }),
            Method::Exact {
                steps,
                bisections,
                scale,
                texture_steps,
                crossings,
                ..
            } => Some(MarchSettings {
                method: MarchMethod::Exact,
                steps,
                bisections,
                scale,
                texture_steps,
                crossings,
                ..MarchSettings::default()
            }),
            Method::Textbook { steps, scale } => Some(MarchSettings {
                method: MarchMethod::Textbook,
                steps,
                scale,
                ..MarchSettings::default()
            }),
        }
    }

    /// The scattering resolution ([`Scale::Full`] for the reference).
    pub fn scale(&self) -> Scale {
        match *self {
            Method::Reference => Scale::Full,
            Method::BruteForce { scale, .. }
            | Method::Hybrid { scale, .. }
            | Method::Exact { scale, .. }
            | Method::Textbook { scale, .. } => scale,
        }
    }

    /// The upsample filter ([`UpsampleFilter::default`] where the method has none).
    pub fn upsample(&self) -> UpsampleFilter {
        match *self {
            Method::Hybrid { upsample, .. } | Method::Exact { upsample, .. } => upsample,
            _ => UpsampleFilter::default(),
        }
    }
}

impl SceneDescription {
    /// Reads and validates a scene file with the default [`LoadOptions`]. Relative paths
    /// inside it (light texture files, glTF files) are resolved against the file's folder and
    /// must stay inside it (see [`crate::load`]).
    ///
    /// # Errors
    ///
    /// [`Error::SceneFile`] naming the file, the JSON field and the problem (unreadable file, bad
    /// JSON, unknown or missing field, a value out of range, an unreadable texture or glTF file);
    /// [`Error::PathOutsideFolder`], [`Error::NotRegularFile`] and [`Error::LimitExceeded`] from
    /// the file rules of [`crate::load`].
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        Self::load_with(path, &LoadOptions::default())
    }

    /// [`load`](Self::load) with the bounds and the folder rule of `options`. The scene file
    /// and every file it names count into one set of totals.
    ///
    /// Errors: [`Error::SceneFile`] for what is wrong in the file; [`Error::PathOutsideFolder`],
    /// [`Error::NotRegularFile`] and [`Error::LimitExceeded`] as they are.
    pub fn load_with(path: impl AsRef<Path>, options: &LoadOptions) -> Result<Self> {
        let path = path.as_ref();
        let shown = path.display().to_string();
        let unreadable = |problem: String| {
            SceneFileError {
                path: shown.clone(),
                field: "(file)".to_owned(),
                problem: format!("cannot read the file: {problem}"),
            }
            .into()
        };
        let mut budget = Budget::new(options);
        let bytes = budget.read(path).map_err(|e| match e {
            Error::FileRead { problem, .. } => unreadable(problem),
            e => e,
        })?;
        let text = String::from_utf8(bytes).map_err(|e| unreadable(e.to_string()))?;
        let folder = crate::load::folder_of(path).map_err(|e| e.to_string());
        Self::parse(&text, folder, &shown, budget)
    }

    /// Parses and validates a scene from JSON text with the default [`LoadOptions`]; relative
    /// paths inside it resolve against `base_dir` and must stay inside it. Errors name the path
    /// `<string>`.
    ///
    /// # Errors
    ///
    /// As [`SceneDescription::load`], with the path `<string>`.
    pub fn from_json(text: &str, base_dir: &Path) -> Result<Self> {
        Self::from_json_with(text, base_dir, &LoadOptions::default())
    }

    /// [`from_json`](Self::from_json) with the bounds and the folder rule of `options` (the
    /// text itself counts against no byte bound).
    pub fn from_json_with(text: &str, base_dir: &Path, options: &LoadOptions) -> Result<Self> {
        let folder = base_dir.canonicalize().map_err(|e| {
            format!(
                "the base folder {} cannot be resolved: {e}",
                base_dir.display()
            )
        });
        Self::parse(text, folder, "<string>", Budget::new(options))
    }

    fn parse(
        text: &str,
        folder: std::result::Result<std::path::PathBuf, String>,
        shown: &str,
        budget: Budget,
    ) -> Result<Self> {
        let at = |field: String, problem: String| -> Error {
            SceneFileError {
                path: shown.to_owned(),
                field,
                problem,
            }
            .into()
        };
        // Through a `Value`, as serde_json keeps the last of duplicate keys there.
        let value: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| at("(json)".to_owned(), format!("invalid JSON: {e}")))?;
        let spec: spec::Scene = serde_path_to_error::deserialize(value).map_err(|e| {
            let message = e.inner().to_string();
            let (field, problem) = spec::located(e.path().iter(), message);
            at(
                if field.is_empty() {
                    "(root)".to_owned()
                } else {
                    field
                },
                problem,
            )
        })?;
        let mut ctx = parse::Ctx {
            folder,
            file: shown,
            budget,
        };
        parse::scene(spec, &mut ctx).map_err(|p| match p.error {
            Some(e) => *e,
            None => at(p.field, p.problem),
        })
    }

    /// Distance along the ray from `origin` in direction `dir` (any non-zero length) to the
    /// nearest triangle of any object (receivers included), in world units, or
    /// `f64::INFINITY` when it hits none (or `dir` is zero or not finite).
    ///
    /// Builds the objects' bounding volume hierarchies on every call: for many rays, use
    /// [`ray_caster`](Self::ray_caster) once.
    pub fn ray_distance(&self, origin: DVec3, dir: DVec3) -> f64 {
        self.ray_caster()(origin, dir)
    }

    /// [`ray_distance`](Self::ray_distance) for many rays: exact f64 Möller–Trumbore on the
    /// world-space triangles (object positions in f64 through the f64 transform, as
    /// [`reference_occluders`](Self::reference_occluders) places them), both sides, edges
    /// included, hits at distance > 0 only, through each object's
    /// [`TriangleMesh::ray_distance`].
    pub fn ray_caster(&self) -> impl Fn(DVec3, DVec3) -> f64 + Send + Sync {
        let meshes: Vec<TriangleMesh> = self.objects.iter().map(world_mesh).collect();
        move |origin, dir| {
            let len = dir.length();
            if !(len.is_finite() && len > 0.0 && origin.is_finite()) {
                return f64::INFINITY;
            }
            let d = dir / len;
            meshes
                .iter()
                .map(|m| m.ray_distance(origin, d))
                .fold(f64::INFINITY, f64::min)
        }
    }

    /// Every shadow-casting object as a world-space [`TriangleMesh`] occluder for
    /// [`crate::reference`].
    pub fn reference_occluders(&self) -> Vec<Occluder> {
        self.objects
            .iter()
            .filter(|o| o.casts_shadow)
            .map(|o| Occluder::Mesh(world_mesh(o)))
            .collect()
    }
}

/// An object's triangles in world space, in f64.
fn world_mesh(o: &SceneObject) -> TriangleMesh {
    TriangleMesh::from_indexed(o.mesh.positions(), o.mesh.indices(), o.transform.as_dmat4())
}
