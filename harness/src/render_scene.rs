//! The `render` example: a JSON scene file rendered headless to EXR, PNG and a JSON report.
//!
//! ```text
//! render SCENE.json [-o OUT] [--method METHOD] [--size WxH] [--exposure E] [--surface-scatter] [--warm-up]
//! ```
//!
//! Writes `OUT.exr` (linear RGB radiance: attenuated surfaces plus in-scatter), `OUT.png`
//! (tone-mapped: exposure, Reinhard, sRGB), `OUT.inscatter.exr` (the in-scattered radiance
//! alone, summed over the lights, before the composite), `OUT.depth.exr` (eye distance per
//! pixel in R, G and B; [`SKY_DISTANCE`] where nothing was drawn) and `OUT.json` (scene, size,
//! method, adapter, the plan, GPU time per pass in ms for the last of three frames, their sum,
//! and the wall-clock time of that frame). `OUT` defaults to `out/STEM` (the scene file's stem,
//! in the folder `out/`, created if missing); a trailing `.png`, `.exr` or `.json` is dropped.
//! A run that would write over one of its inputs (the scene file or a file it names) is
//! refused before anything is written. `-h` / `--help` prints [`help`].
//!
//! `METHOD` (default: the scene file's own `method`), one of [`METHODS`] (the parser and the
//! help are both made from that list):
//! * `reference`: the f64 CPU integrator ([`volshadow::reference::inscatter_image`]) with
//!   exact visibility, composited on the CPU onto the same app-drawn frame;
//! * `analytic`: the GPU with no occluders passed — unshadowed airlight, the cost floor;
//! * `exact[:SCALE[:FILTER[:CROSSINGS]]]`: the GPU's exact integration between shadow-volume
//!   crossings (the library's default method);
//! * `brute[:STEPS[:SCALE[:BISECTIONS]]]` (or `brute_force`): the GPU brute-force march;
//! * `hybrid[:STEPS[:SCALE[:FILTER[:BISECTIONS]]]]`: the GPU hybrid;
//! * `textbook[:STEPS[:SCALE]]`: the Riemann sum in distance most engines use.
//!
//! FILTER is one of `bilinear`, `3x3` (depth-aware 3×3, the default) or
//! `separable[,TAPS,SIGMA_SPATIAL,SIGMA_DEPTH]` (default `separable,7,1.5,0.05`).
//! Defaults: 64 steps, SCALE 1 (full resolution; 2 or 4 divide the output size), 0 bisections,
//! CROSSINGS [`volshadow::nodes::DEFAULT_CROSSINGS`].
//! Everything else is `Settings::default()`'s (256² F′ table, 1024² shadow maps, occluders
//! culled below 1e-3 of the in-scatter; `march_settings()`' 32 texture steps outside the extents).
//! `--size` overrides the file's size (the camera keeps its vertical field of view);
//! `--exposure` replaces the automatic exposure ([`auto_exposure`]) of the PNG.
//! `--surface-scatter` (GPU methods) passes the app's normals and albedo (the objects'
//! `albedo`) as `Frame::surfaces`, so the composite adds the light the fog scatters onto the
//! surfaces, and also writes `OUT.surface.exr`: the radiance that term adds to `OUT.exr` alone
//! (linear, attenuated by the fog between surface and eye as the rest of the surface colour,
//! 0 on sky), the difference from the same frame without it.
//!
//! The app's own frame is drawn by [`draw_app_frame`]: every object of the scene, receivers
//! included, lit with surface shadows from the shadow casters (volshadow's shadow-map node and
//! `volshadow::SHADOW_WGSL`), whatever the method.

use std::path::{Path, PathBuf};
use std::time::Instant;

use lexopt::prelude::*;
use volshadow::glam::DVec3;
use volshadow::nodes::{Scale, UpsampleFilter};
use volshadow::reference::{self, TexturedSpot};
use volshadow::scene_file::{Method, SceneDescription};
use volshadow::{
    Cache, Camera, Frame, FrameLight, HeadlessGpu, Light, LightKind, Occluder, OccluderMesh,
    Settings, Surfaces, VolumetricShadows,
};

use crate::app::{
    auto_exposure, eye_distances, parse_size, read_depth, read_inscatter, render_frames, rgb,
    timings_json, tone_map, with_aspect, write_exr, write_png, BoxError, FRAMES, SKY_DISTANCE,
};
use crate::cli::{default_output, input_files, output_base, refuse_overwrite, usage_line, Parsed};
use crate::raster::{
    default_ambient, draw_app_frame, surface_shadow_maps, texture_desc, AppFrame, DrawLight,
    DrawObject,
};

/// The command line, for error messages (`--help` prints [`help`]).
pub const USAGE: &str = "usage: render SCENE.json [-o OUT] [--method METHOD] [--size WxH] \
[--exposure E] [--surface-scatter] [--warm-up] [-h | --help]";

/// Which method a [`METHODS`] entry is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MethodKind {
    Reference,
    Analytic,
    Exact,
    BruteForce,
    Hybrid,
    Textbook,
}

/// One `--method` the parser accepts: its name (and other spellings), its `:`-separated
/// parameters in order, and what it is.
#[derive(Debug, Clone, Copy)]
pub struct MethodSyntax {
    pub kind: MethodKind,
    pub name: &'static str,
    pub aliases: &'static [&'static str],
    pub params: &'static [&'static str],
    pub about: &'static str,
}

impl MethodSyntax {
    /// `name[:P1[:P2]]`.
    pub fn syntax(&self) -> String {
        let mut text = self.name.to_string();
        for p in self.params {
            text.push_str("[:");
            text.push_str(p);
        }
        text.push_str(&"]".repeat(self.params.len()));
        text
    }
}

/// Every method `--method` accepts: [`RenderMethod::parse`] looks names up here and [`help`]
/// lists them, so the two cannot differ.
pub const METHODS: [MethodSyntax; 6] = [
    MethodSyntax {
        kind: MethodKind::Reference,
        name: "reference",
        aliases: &[],
        params: &[],
        about: "the f64 CPU integrator with exact visibility, composited on the CPU",
    },
    MethodSyntax {
        kind: MethodKind::Analytic,
        name: "analytic",
        aliases: &[],
        params: &[],
        about: "the GPU with no occluders passed: unshadowed airlight, the cost floor",
    },
    MethodSyntax {
        kind: MethodKind::Exact,
        name: "exact",
        aliases: &[],
        params: &["SCALE", "FILTER", "CROSSINGS"],
        about: "the GPU's exact integration between shadow-volume crossings (the default)",
    },
    MethodSyntax {
        kind: MethodKind::BruteForce,
        name: "brute",
        aliases: &["brute_force"],
        params: &["STEPS", "SCALE", "BISECTIONS"],
        about: "the GPU brute-force march over the whole ray",
    },
    MethodSyntax {
        kind: MethodKind::Hybrid,
        name: "hybrid",
        aliases: &[],
        params: &["STEPS", "SCALE", "FILTER", "BISECTIONS"],
        about: "the GPU hybrid: marched only between the shadow volumes' extents",
    },
    MethodSyntax {
        kind: MethodKind::Textbook,
        name: "textbook",
        aliases: &[],
        params: &["STEPS", "SCALE"],
        about: "the Riemann sum in distance most engines use (the report's baseline)",
    },
];

/// `render --help`: the usage, every option and every method of [`METHODS`].
pub fn help() -> String {
    let mut methods = String::new();
    for m in &METHODS {
        let mut syntax = m.syntax();
        for alias in m.aliases {
            syntax.push_str(&format!(" (or {alias})"));
        }
        methods.push_str(&format!("      {syntax}\n          {}\n", m.about));
    }
    format!(
        "{USAGE}

Renders a JSON scene file headless: writes OUT.exr (linear radiance), OUT.png (tone-mapped),
OUT.inscatter.exr (the in-scattered light alone), OUT.depth.exr (eye distance) and OUT.json
(the plan and the timings), and OUT.surface.exr with --surface-scatter.

options:
  -o, --output OUT   output path without extension (default: out/STEM, STEM the scene file's
                     stem; a trailing .png, .exr or .json is dropped; folders are created).
                     A run that would write over an input file is refused.
  --method METHOD    how the in-scatter is computed (default: the scene file's method), one of
{methods}                     STEPS: steps per marched interval (default 64); SCALE: 1, 2 or 4, the
                     scattering resolution's divisor (default 1); FILTER: bilinear, 3x3 (the
                     default) or separable[,TAPS,SIGMA_SPATIAL,SIGMA_DEPTH]; BISECTIONS:
                     default 0; CROSSINGS: shadow-volume faces kept per pixel (default {}).
  --size WxH         image size (default: the scene file's; the vertical field of view is kept)
  --exposure E       the PNG's exposure (default: automatic)
  --surface-scatter  add the light the fog scatters onto the surfaces (GPU methods) and write
                     OUT.surface.exr, that term alone
  --warm-up          build every pipeline the settings and the scene's lights can use before
                     the first frame (volshadow::Settings::warm_up) and print how long it took
  -h, --help         this help",
        volshadow::nodes::DEFAULT_CROSSINGS
    )
}

/// How to compute the in-scatter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RenderMethod {
    /// The f64 reference on the CPU.
    Reference,
    /// The GPU without occluders.
    Analytic,
    /// A GPU method of the scene format (never [`Method::Reference`]).
    Gpu(Method),
}

impl RenderMethod {
    /// The scene file's method.
    pub fn from_scene(method: Method) -> Self {
        match method {
            Method::Reference => RenderMethod::Reference,
            other => RenderMethod::Gpu(other),
        }
    }

    /// Parses the `--method` syntax: a name of [`METHODS`] and its `:`-separated parameters.
    pub fn parse(text: &str) -> Result<Self, BoxError> {
        let mut parts = text.split(':');
        let kind = parts.next().unwrap_or_default();
        let rest: Vec<&str> = parts.collect();
        let bad = |what: &str| -> BoxError { format!("--method {text:?}: {what}").into() };
        let Some(entry) = METHODS
            .iter()
            .find(|m| m.name == kind || m.aliases.contains(&kind))
        else {
            let names: Vec<String> = METHODS.iter().map(|m| m.syntax()).collect();
            return Err(bad(&format!("expected one of {}", names.join(", "))));
        };
        if rest.len() > entry.params.len() {
            return Err(bad(&format!(
                "at most {} ':'-separated parameters ({})",
                entry.params.len(),
                entry.syntax()
            )));
        }
        // A parameter by its name in the entry, so the order is the table's.
        let param = |name: &str| -> Option<&str> {
            let i = entry.params.iter().position(|p| *p == name)?;
            rest.get(i).copied()
        };
        let number = |name: &str, default: u32| -> Result<u32, BoxError> {
            param(name).map_or(Ok(default), |s| {
                s.parse()
                    .map_err(|_| bad(&format!("{name} must be a whole number, got {s:?}")))
            })
        };
        let scale = || -> Result<Scale, BoxError> {
            Scale::from_divisor(number("SCALE", 1)?).map_err(|e| bad(&e.to_string()))
        };
        let filter = || -> Result<UpsampleFilter, BoxError> {
            match param("FILTER") {
                None => Ok(UpsampleFilter::DepthAware3x3),
                Some(f) => parse_filter(f).map_err(|e| bad(&e.to_string())),
            }
        };
        Ok(match entry.kind {
            MethodKind::Reference => RenderMethod::Reference,
            MethodKind::Analytic => RenderMethod::Analytic,
            MethodKind::BruteForce => RenderMethod::Gpu(Method::BruteForce {
                steps: number("STEPS", 64)?,
                scale: scale()?,
                bisections: number("BISECTIONS", 0)?,
            }),
            MethodKind::Hybrid => RenderMethod::Gpu(Method::Hybrid {
                steps: number("STEPS", 64)?,
                scale: scale()?,
                upsample: filter()?,
                bisections: number("BISECTIONS", 0)?,
                texture_steps: 32,
            }),
            MethodKind::Exact => {
                let defaults = volshadow::nodes::MarchSettings::default();
                RenderMethod::Gpu(Method::Exact {
                    steps: defaults.steps,
                    scale: scale()?,
                    upsample: filter()?,
                    bisections: defaults.bisections,
                    texture_steps: 32,
                    crossings: number("CROSSINGS", volshadow::nodes::DEFAULT_CROSSINGS)?,
                })
            }
            MethodKind::Textbook => RenderMethod::Gpu(Method::Textbook {
                steps: number("STEPS", 64)?,
                scale: scale()?,
            }),
        })
    }

    /// The method in the `--method` syntax, every parameter spelt out.
    pub fn describe(&self) -> String {
        match *self {
            RenderMethod::Reference => "reference".into(),
            RenderMethod::Analytic => "analytic".into(),
            RenderMethod::Gpu(Method::BruteForce {
                steps,
                scale,
                bisections,
            }) => {
                format!("brute:{steps}:{}:{bisections}", scale.divisor())
            }
            RenderMethod::Gpu(Method::Hybrid {
                steps,
                scale,
                upsample,
                bisections,
                ..
            }) => {
                let filter = match upsample {
                    UpsampleFilter::Bilinear => "bilinear".to_string(),
                    UpsampleFilter::DepthAware3x3 => "3x3".to_string(),
                    UpsampleFilter::Separable {
                        taps,
                        sigma_spatial,
                        sigma_depth,
                    } => {
                        format!("separable,{taps},{sigma_spatial},{sigma_depth}")
                    }
                    other => format!("{other:?}"),
                };
                format!("hybrid:{steps}:{}:{filter}:{bisections}", scale.divisor())
            }
            RenderMethod::Gpu(other) => format!("{other:?}"),
        }
    }
}

/// `bilinear`, `3x3` / `depth_aware_3x3`, or `separable[,TAPS,SIGMA_SPATIAL,SIGMA_DEPTH]`.
fn parse_filter(text: &str) -> Result<UpsampleFilter, BoxError> {
    let mut parts = text.split(',');
    match parts.next().unwrap_or_default() {
        "bilinear" => Ok(UpsampleFilter::Bilinear),
        "3x3" | "depth_aware_3x3" => Ok(UpsampleFilter::DepthAware3x3),
        "separable" => {
            let rest: Vec<&str> = parts.collect();
            let filter = match rest.as_slice() {
                [] => UpsampleFilter::Separable {
                    taps: 7,
                    sigma_spatial: 1.5,
                    sigma_depth: 0.05,
                },
                [taps, spatial, depth] => UpsampleFilter::Separable {
                    taps: taps
                        .parse()
                        .map_err(|_| format!("TAPS {taps:?} is not a number"))?,
                    sigma_spatial: spatial
                        .parse()
                        .map_err(|_| format!("SIGMA_SPATIAL {spatial:?} is not a number"))?,
                    sigma_depth: depth
                        .parse()
                        .map_err(|_| format!("SIGMA_DEPTH {depth:?} is not a number"))?,
                },
                _ => return Err("separable takes no or three ','-separated parameters".into()),
            };
            filter.validate()?;
            Ok(filter)
        }
        other => Err(format!("unknown FILTER {other:?} (bilinear, 3x3, separable)").into()),
    }
}

/// The parsed command line.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// The scene file.
    pub scene: PathBuf,
    /// Output paths without extension.
    pub out: PathBuf,
    /// `None`: the scene's own method.
    pub method: Option<RenderMethod>,
    /// `None`: the scene's own size.
    pub size: Option<(u32, u32)>,
    /// `None`: [`auto_exposure`].
    pub exposure: Option<f64>,
    /// Add the light scattered onto surfaces and write `OUT.surface.exr`.
    pub surface_scatter: bool,
    /// Build the pipelines before the first frame (`Settings::warm_up`).
    pub warm_up: bool,
}

impl Options {
    /// Parses the arguments after the program name: the options, or [`Parsed::Help`] for
    /// `-h` / `--help` (whatever else is given).
    pub fn parse(args: &[String]) -> Result<Parsed<Self>, BoxError> {
        let mut scene = None;
        let (mut out, mut method, mut size, mut exposure) = (None, None, None, None);
        let (mut surface_scatter, mut warm_up) = (false, false);
        if args.iter().any(|a| a == "-h" || a == "--help") {
            return Ok(Parsed::Help);
        }
        let mut parser = lexopt::Parser::from_args(args);
        while let Some(arg) = parser.next()? {
            match arg {
                Short('o') | Long("output") => out = Some(PathBuf::from(parser.value()?)),
                Long("method") => method = Some(RenderMethod::parse(&parser.value()?.string()?)?),
                Long("size") => size = Some(parse_size(&parser.value()?.string()?)?),
                Long("exposure") => {
                    let e: f64 = parser.value()?.parse()?;
                    if !(e.is_finite() && e > 0.0) {
                        return Err(format!("--exposure must be positive, got {e}").into());
                    }
                    exposure = Some(e);
                }
                Long("surface-scatter") => surface_scatter = true,
                Long("warm-up") => warm_up = true,
                Short('h') | Long("help") => return Ok(Parsed::Help),
                Value(path) if scene.is_none() => scene = Some(PathBuf::from(path)),
                _ => return Err(format!("{}\n{USAGE}", arg.unexpected()).into()),
            }
        }
        let scene: PathBuf = scene.ok_or_else(|| format!("no scene file given\n{USAGE}"))?;
        let out = out.unwrap_or_else(|| default_output(&scene, "render"));
        let out = output_base(out, &["png", "exr", "json"])?;
        Ok(Parsed::Run(Options {
            scene,
            out,
            method,
            size,
            exposure,
            surface_scatter,
            warm_up,
        }))
    }

    /// Every file the run writes: `OUT.exr`, `.png`, `.inscatter.exr`, `.depth.exr`, `.json`,
    /// and `.surface.exr` with `--surface-scatter`.
    pub fn outputs(&self) -> Vec<PathBuf> {
        let mut suffixes = vec![".exr", ".png", ".inscatter.exr", ".depth.exr", ".json"];
        if self.surface_scatter {
            suffixes.push(".surface.exr");
        }
        suffixes.into_iter().map(|s| self.path(s)).collect()
    }

    /// `OUT` followed by `suffix` (e.g. `".inscatter.exr"`).
    pub fn path(&self, suffix: &str) -> PathBuf {
        let mut s = self.out.as_os_str().to_owned();
        s.push(suffix);
        s.into()
    }
}

/// A scene file's frame on the GPU, as an application would have it: the light textures, the
/// app's own colour and depth ([`draw_app_frame`]) and the shadow casters' meshes.
pub struct GpuScene<'a> {
    /// The scene.
    pub scene: &'a SceneDescription,
    /// The camera (the scene's, or its aspect-corrected copy).
    pub camera: &'a Camera,
    /// Output size.
    pub size: (u32, u32),
    /// Per light, its uploaded texture.
    pub textures: Vec<Option<wgpu::Texture>>,
    /// The app's frame.
    pub app: AppFrame,
    /// Shadow casters: GPU mesh and object → world (none for the analytic floor).
    pub casters: Vec<(OccluderMesh, volshadow::glam::Mat4)>,
    /// [`frame`](Self::frame) passes the app's normals and albedo (`Frame::surfaces`).
    pub surfaces: bool,
}

impl<'a> GpuScene<'a> {
    /// Uploads the light textures and meshes and draws the app's frame; `shadows = false`
    /// passes no occluders (the unshadowed, analytic floor).
    pub fn new(
        gpu: &HeadlessGpu,
        scene: &'a SceneDescription,
        camera: &'a Camera,
        size: (u32, u32),
        shadows: bool,
    ) -> Result<Self, BoxError> {
        let textures: Vec<Option<wgpu::Texture>> = scene
            .lights
            .iter()
            .map(|l| {
                l.texture
                    .as_ref()
                    .map(|t| t.upload(&gpu.device, &gpu.queue))
            })
            .collect();
        // The shadow casters, uploaded once: the app's surface shadows always use them; the
        // volumetric shadows only when `shadows`.
        let meshes: Vec<(OccluderMesh, volshadow::glam::Mat4)> = scene
            .objects
            .iter()
            .filter(|o| o.casts_shadow)
            .map(|o| (OccluderMesh::new(&gpu.device, &o.mesh), o.transform))
            .collect();
        let occluders: Vec<Occluder> = meshes
            .iter()
            .map(|(mesh, transform)| Occluder {
                mesh,
                transform: *transform,
            })
            .collect();
        let lights: Vec<Light> = scene.lights.iter().map(|l| l.light).collect();
        let maps = surface_shadow_maps(gpu, &lights, &occluders, camera)?;
        let draw_lights: Vec<DrawLight> = scene
            .lights
            .iter()
            .zip(&textures)
            .zip(&maps)
            .map(|((l, t), m)| DrawLight {
                light: l.light,
                texture: t.as_ref(),
                shadow: m.as_ref().and_then(|m| m.shadow_map()),
            })
            .collect();
        let objects: Vec<DrawObject> = scene
            .objects
            .iter()
            .map(|o| DrawObject {
                mesh: &o.mesh,
                transform: o.transform,
                albedo: o.albedo,
            })
            .collect();
        let ambient = default_ambient(camera, &draw_lights, &objects, &scene.medium);
        let app = draw_app_frame(
            gpu,
            camera,
            size,
            &objects,
            &draw_lights,
            &scene.medium,
            ambient,
        )?;
        drop(draw_lights);
        drop(occluders);
        let casters = if shadows { meshes } else { Vec::new() };
        Ok(Self {
            scene,
            camera,
            size,
            textures,
            app,
            casters,
            surfaces: false,
        })
    }

    /// The frame's lights, with their textures.
    pub fn lights(&self) -> Vec<FrameLight<'_>> {
        self.scene
            .lights
            .iter()
            .zip(&self.textures)
            .map(|(l, t)| FrameLight {
                light: l.light,
                texture: t.as_ref(),
                casters: None,
                texture_channels: Default::default(),
            })
            .collect()
    }

    /// The frame's occluders.
    pub fn occluders(&self) -> Vec<Occluder<'_>> {
        self.casters
            .iter()
            .map(|(mesh, transform)| Occluder {
                mesh,
                transform: *transform,
            })
            .collect()
    }

    /// A frame of the scene with `lights` and `occluders` (from [`lights`](Self::lights) and
    /// [`occluders`](Self::occluders), or a subset).
    pub fn frame<'f>(
        &'f self,
        lights: &'f [FrameLight<'f>],
        occluders: &'f [Occluder<'f>],
    ) -> Frame<'f> {
        Frame {
            camera: self.camera,
            lights,
            medium: &self.scene.medium,
            occluders,
            scene_color: &self.app.color,
            scene_depth: &self.app.depth,
            surfaces: self.surfaces.then_some(Surfaces {
                normal: &self.app.normal,
                albedo: &self.app.albedo,
            }),
        }
    }

    /// An `Rgba32Float` output target of the frame's size (`RENDER_ATTACHMENT |
    /// STORAGE_BINDING | COPY_SRC`: the composite writes it with a compute pass).
    pub fn output(&self, gpu: &HeadlessGpu) -> wgpu::Texture {
        self.output_with(gpu, wgpu::TextureUsages::STORAGE_BINDING)
    }

    /// [`output`](Self::output) with `RENDER_ATTACHMENT | COPY_SRC | extra` (without
    /// `STORAGE_BINDING`, the composite goes through the rasteriser).
    pub fn output_with(&self, gpu: &HeadlessGpu, extra: wgpu::TextureUsages) -> wgpu::Texture {
        gpu.device.create_texture(&texture_desc(
            "output",
            self.size,
            wgpu::TextureFormat::Rgba32Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC | extra,
        ))
    }
}

/// The f64 reference in-scatter of every pixel, summed over the scene's lights (textured spots
/// with their textures), exact visibility against the shadow casters.
pub fn reference_inscatter(
    scene: &SceneDescription,
    camera: &Camera,
    (width, height): (u32, u32),
) -> Vec<DVec3> {
    let occluders = scene.reference_occluders();
    let mut inscatter = vec![DVec3::ZERO; (width * height) as usize];
    let ds = scene.ray_caster();
    for l in &scene.lights {
        let image = match (l.light, &l.texture) {
            (Light::Spot(spot), Some(texture)) => {
                let textured = TexturedSpot { spot, texture };
                reference::inscatter_image(
                    camera,
                    width,
                    height,
                    &ds,
                    &scene.medium,
                    &textured,
                    &occluders,
                )
            }
            (light, _) if light.radius() > 0.0 => reference::inscatter_image_soft(
                camera,
                width,
                height,
                &ds,
                &scene.medium,
                &light,
                &soft_occluders(scene),
            ),
            (light, _) => reference::inscatter_image(
                camera,
                width,
                height,
                &ds,
                &scene.medium,
                &light,
                &occluders,
            ),
        };
        inscatter
            .iter_mut()
            .zip(image)
            .for_each(|(sum, v)| *sum += v);
    }
    inscatter
}

/// The occluders for a light with a radius: an object whose world-space vertices all lie on
/// one sphere (to 1e-4 of its radius: a tessellated sphere) is that exact sphere, whose
/// visible fraction the reference computes in closed form; any other is its mesh, sampled
/// (about a second per pixel and far slower than the sphere, which makes the soft scene's
/// reference affordable at the report's sizes).
fn soft_occluders(scene: &SceneDescription) -> Vec<reference::Occluder> {
    let mut out = Vec::new();
    for (o, mesh) in scene
        .objects
        .iter()
        .filter(|o| o.casts_shadow)
        .zip(scene.reference_occluders())
    {
        let t = o.transform.as_dmat4();
        let p: Vec<DVec3> = o
            .mesh
            .positions()
            .iter()
            .map(|v| t.transform_point3(v.as_dvec3()))
            .collect();
        let lo = p.iter().fold(DVec3::INFINITY, |a, &b| a.min(b));
        let hi = p.iter().fold(DVec3::NEG_INFINITY, |a, &b| a.max(b));
        let c = 0.5 * (lo + hi);
        let (near, far) = p.iter().fold((f64::INFINITY, 0.0f64), |(n, f), q| {
            let d = q.distance(c);
            (n.min(d), f.max(d))
        });
        out.push(if far > 0.0 && far - near <= 1e-4 * far {
            reference::Sphere::new(c, far).into()
        } else {
            mesh
        });
    }
    out
}

/// What [`render`] produced.
pub struct Rendered {
    /// The five files, in the order exr, png, inscatter exr, depth exr, json.
    pub files: [PathBuf; 5],
    /// The JSON report, as written.
    pub report: serde_json::Value,
}

/// Parses `args` (after the program name) and renders (what the tests call; `--help`, which
/// the binary prints, is an error here).
pub fn run(args: &[String]) -> Result<Rendered, BoxError> {
    match Options::parse(args)? {
        Parsed::Run(options) => render(&options),
        Parsed::Help => Err(format!("--help renders nothing\n{}", usage_line(USAGE)).into()),
    }
}

/// Renders a scene file as `options` say and writes the five files (six with
/// `--surface-scatter`); refused with [`WouldOverwriteInput`](crate::cli::WouldOverwriteInput)
/// before anything is read or written when one of them is an input file.
pub fn render(options: &Options) -> Result<Rendered, BoxError> {
    refuse_overwrite(&input_files(&options.scene), &options.outputs())?;
    let scene = SceneDescription::load(&options.scene)?;
    let size = options.size.unwrap_or(scene.size);
    let (width, height) = size;
    let camera = if options
        .size
        .is_some_and(|s| s.0 * scene.size.1 != s.1 * scene.size.0)
    {
        with_aspect(&scene.camera, width as f32 / height as f32)?
    } else {
        scene.camera
    };
    let method = options
        .method
        .unwrap_or_else(|| RenderMethod::from_scene(scene.method));
    let gpu = HeadlessGpu::with_optional_features(wgpu::Features::TIMESTAMP_QUERY)?;
    println!(
        "scene {:?} at {width}x{height}, method {}",
        scene.name,
        method.describe()
    );
    println!("adapter: {}", gpu.adapter_summary());

    if options.surface_scatter && method == RenderMethod::Reference {
        return Err(
            "--surface-scatter needs a GPU method (the reference has no surface term)".into(),
        );
    }
    let mut gpu_scene = GpuScene::new(
        &gpu,
        &scene,
        &camera,
        size,
        method != RenderMethod::Analytic,
    )?;
    gpu_scene.surfaces = options.surface_scatter;
    let app = &gpu_scene.app;
    let mut surface = None;
    let distances = eye_distances(&camera, size, &read_depth(&gpu, &app.depth)?);

    let (radiance, inscatter, plan, timings, wall_ms) = match method {
        RenderMethod::Reference => {
            let start = Instant::now();
            let inscatter = reference_inscatter(&scene, &camera, size);
            let wall_ms = start.elapsed().as_secs_f64() * 1e3;
            // The composite of the GPU path, on the CPU: Ls·exp(−σt·ds) + in-scatter, with the
            // surface distance of the app's depth buffer.
            let color = gpu.read_rgba32f(&app.color)?;
            let radiance: Vec<DVec3> = color
                .iter()
                .zip(&distances)
                .zip(&inscatter)
                .map(|((c, &ds), s)| rgb(c) * reference::transmittance(&scene.medium, ds) + *s)
                .collect();
            let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
            let plan = vec![format!(
                "  run   frame    reference      f64 CPU integrator, exact visibility, {} light(s), {threads} thread(s)",
                scene.lights.len()
            )];
            (radiance, inscatter, plan, Vec::new(), wall_ms)
        }
        RenderMethod::Analytic | RenderMethod::Gpu(_) => {
            let gpu_method = match method {
                RenderMethod::Gpu(m) => m,
                _ => Method::default(),
            };
            let march = gpu_method
                .march_settings()
                .ok_or("a GPU method has march settings")?;
            let settings = Settings {
                march,
                upsample: gpu_method.upsample(),
                output_format: wgpu::TextureFormat::Rgba32Float,
                ..Settings::default()
            };
            let cache = Cache::new(&gpu.device);
            let (lights, occluders) = (gpu_scene.lights(), gpu_scene.occluders());
            if options.warm_up {
                let kinds: Vec<LightKind> = lights.iter().map(FrameLight::kind).collect();
                let start = Instant::now();
                settings.warm_up(&gpu.device, &cache, &kinds)?;
                println!(
                    "warm-up: the pipelines for {kinds:?} built in {:.1} ms",
                    start.elapsed().as_secs_f64() * 1e3
                );
            }
            let mut volumetric = VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, settings)?;
            let output = gpu_scene.output(&gpu);
            let frame = gpu_scene.frame(&lights, &occluders);
            let stats = render_frames(&gpu, &mut volumetric, &frame, &output)?;
            let radiance: Vec<DVec3> = gpu.read_rgba32f(&output)?.iter().map(rgb).collect();
            let inscatter = read_inscatter(&gpu, &volumetric, &frame)?;
            if options.surface_scatter {
                // The same frame without the term: the difference is what it adds.
                let without = Frame {
                    surfaces: None,
                    ..frame
                };
                volumetric.prepare(&gpu.device, &gpu.queue, &without)?;
                let mut encoder = gpu.device.create_command_encoder(&Default::default());
                volumetric.encode(&mut encoder, &output)?;
                gpu.submit_and_wait(encoder)?;
                let base = gpu.read_rgba32f(&output)?;
                let added = radiance.iter().zip(&base).zip(&distances);
                surface = Some(
                    added
                        .map(|((r, b), d)| {
                            if d.is_finite() {
                                *r - rgb(b)
                            } else {
                                DVec3::ZERO
                            }
                        })
                        .collect::<Vec<DVec3>>(),
                );
            }
            (
                radiance,
                inscatter,
                stats.plan,
                stats.timings,
                stats.wall_ms,
            )
        }
    };

    // Files.
    let files = [".exr", ".png", ".inscatter.exr", ".depth.exr", ".json"].map(|s| options.path(s));
    if let Some(dir) = files[0].parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    let exposure = options.exposure.unwrap_or_else(|| auto_exposure(&radiance));
    write_exr(&files[0], size, &radiance)?;
    write_png(&files[1], &tone_map(size, &radiance, exposure))?;
    write_exr(&files[2], size, &inscatter)?;
    let depth: Vec<DVec3> = distances
        .iter()
        .map(|&d| {
            DVec3::splat(if d.is_finite() {
                d
            } else {
                f64::from(SKY_DISTANCE)
            })
        })
        .collect();
    write_exr(&files[3], size, &depth)?;
    if let Some(surface) = &surface {
        write_exr(&options.path(".surface.exr"), size, surface)?;
    }
    let (passes, gpu_ms) = timings_json(&timings);
    let name = |p: &Path| p.display().to_string();
    let report = serde_json::json!({
        "scene": scene.name,
        "scene_file": name(&options.scene),
        "size": [width, height],
        "method": method.describe(),
        "adapter": gpu.adapter_summary(),
        "frames": if method == RenderMethod::Reference { 1 } else { FRAMES },
        "plan": plan,
        "passes": passes,
        "gpu_ms": gpu_ms,
        "wall_ms": wall_ms,
        "exposure": exposure,
        "sky_distance": SKY_DISTANCE,
        "files": files[..4].iter().map(|p| name(p)).collect::<Vec<_>>(),
    });
    let text = serde_json::to_string_pretty(&report)?;
    std::fs::write(&files[4], text + "\n")
        .map_err(|e| format!("cannot write {}: {e}", files[4].display()))?;
    println!(
        "{}: {} ms wall clock; wrote {}.{{exr,png,inscatter.exr,depth.exr,json}}",
        method.describe(),
        format_args!("{wall_ms:.1}"),
        options.out.display()
    );
    Ok(Rendered { files, report })
}
