//! The `gltf` example: every mesh of a glTF model as an occluder in hazy fog (feature `gltf`).
//!
//! ```text
//! gltf MODEL.gltf|MODEL.glb [-o OUT] [--size WxH]
//! ```
//!
//! The scene is built around the model so that any model, of any size, shows its dark shafts:
//! with `c` the centre and `r` the half-diagonal of the meshes' combined world bounds,
//!
//! * the camera looks at `c` from the front (+z), slightly above (elevation about 8.5°), far
//!   enough for the bounds' sphere to fit the view with room to spare, horizontally as well as
//!   vertically (40° vertical field of view; [`framing_camera`]); reversed-Z infinite projection;
//! * a ground plane (a receiver, not an occluder) lies under the bounds, 12 `r` across each way;
//! * a point light sits above and behind the model (`c + r·(0.3, 1.0, −2.2)`), in view, so the
//!   shadows the model casts run down and towards the camera through forward-scattering fog;
//! * hazy fog: `σs = (0.14, 0.15, 0.17)/r`, `σa = 0.01/r`, Henyey–Greenstein g = 0.5, and
//!   intensity `40 r²`, so the picture does not depend on the model's units.
//!
//! It prints each mesh's topology (triangles, closed or open, boundary and non-manifold edges)
//! and what it means for the shadow volume, renders through `VolumetricShadows` with the
//! default (real-time) settings, prints the plan and per-pass GPU times, and writes `OUT.png`
//! (tone-mapped) and `OUT.inscatter.exr` (the in-scattered radiance alone, linear RGB, as
//! `render` writes it). `OUT` defaults to `out/STEM` (the model's stem, in the folder `out/`,
//! created if missing); a trailing `.png` or `.exr` is dropped. A run that would write over an
//! input (the model, or a buffer or image it names) is refused before anything is written.
//! Size 800×500 unless `--size`. `-h` / `--help` prints [`HELP`].

use std::path::PathBuf;

use lexopt::prelude::*;
use volshadow::glam::{DVec3, Mat4, Vec2, Vec3};
use volshadow::scene::shapes;
use volshadow::{
    AdapterKind, Cache, Camera, Frame, FrameLight, HeadlessGpu, Light, Medium, Occluder,
    OccluderMesh, PhaseFunction, PointLight, Settings, VolumetricShadows,
};

use crate::app::{
    auto_exposure, parse_size, read_inscatter, render_frames, rgb, tone_map, write_exr, write_png,
    BoxError, FrameStats,
};
use crate::cli::{default_output, input_files, output_base, refuse_overwrite, usage_line, Parsed};
use crate::raster::{
    default_ambient, draw_app_frame, surface_shadow_maps, texture_desc, DrawLight, DrawObject,
};

/// `gltf --help` (its first line is the usage line of error messages).
pub const HELP: &str = "\
usage: gltf MODEL.gltf|MODEL.glb [-o OUT] [--size WxH] [-h | --help]

Loads every mesh of a glTF model as an occluder, prints each mesh's topology (closed or open,
boundary and non-manifold edges) and what it means for its shadow volume, frames the model over
a ground plane with a point light above and behind it in hazy fog, and writes OUT.png
(tone-mapped) and OUT.inscatter.exr (the in-scattered light alone, linear RGB).

options:
  -o, --output OUT  output path without extension (default: out/STEM, STEM the model's stem;
                    a trailing .png or .exr is dropped; folders are created). A run that would
                    write over an input file (the model, its buffers or images) is refused.
  --size WxH        image size (default 800x500)
  -h, --help        this help";

/// The usage line, for error messages.
pub const USAGE: &str = "usage: gltf MODEL.gltf|MODEL.glb [-o OUT] [--size WxH] [-h | --help]";

/// The parsed command line.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// The model.
    pub model: PathBuf,
    /// Output paths without extension: `OUT.png` and `OUT.inscatter.exr` are written.
    pub out: PathBuf,
    /// Output size, default 800×500.
    pub size: (u32, u32),
}

impl Options {
    /// Parses the arguments after the program name: the options, or [`Parsed::Help`] for
    /// `-h` / `--help` (whatever else is given).
    pub fn parse(args: &[String]) -> Result<Parsed<Self>, BoxError> {
        if args.iter().any(|a| a == "-h" || a == "--help") {
            return Ok(Parsed::Help);
        }
        let (mut model, mut out, mut size) = (None, None, (800, 500));
        let mut parser = lexopt::Parser::from_args(args);
        while let Some(arg) = parser.next()? {
            match arg {
                Short('o') | Long("output") => out = Some(PathBuf::from(parser.value()?)),
                Long("size") => size = parse_size(&parser.value()?.string()?)?,
                Short('h') | Long("help") => return Ok(Parsed::Help),
                Value(path) if model.is_none() => model = Some(PathBuf::from(path)),
                _ => return Err(format!("{}\n{USAGE}", arg.unexpected()).into()),
            }
        }
        let model: PathBuf = model.ok_or_else(|| format!("no model given\n{USAGE}"))?;
        let out: PathBuf = out.unwrap_or_else(|| default_output(&model, "gltf"));
        let out = output_base(out, &["png", "exr"])?;
        Ok(Parsed::Run(Options { model, out, size }))
    }

    /// The files the run writes: `OUT.png` and `OUT.inscatter.exr`.
    pub fn outputs(&self) -> Vec<PathBuf> {
        vec![self.path(".png"), self.path(".inscatter.exr")]
    }

    /// `OUT` followed by `suffix` (e.g. `".inscatter.exr"`).
    pub fn path(&self, suffix: &str) -> PathBuf {
        let mut s = self.out.as_os_str().to_owned();
        s.push(suffix);
        s.into()
    }
}

/// What [`render`] produced.
pub struct Rendered {
    /// The PNG written.
    pub png: PathBuf,
    /// The in-scatter EXR written.
    pub inscatter_exr: PathBuf,
    /// Each mesh's one-line topology report, as printed.
    pub summaries: Vec<String>,
    /// The in-scattered radiance (row-major from the top), summed over the lights.
    pub inscatter: Vec<DVec3>,
    /// The composited linear radiance.
    pub radiance: Vec<DVec3>,
    /// Plan and timings of the last frame.
    pub stats: FrameStats,
}

/// Parses `args` (after the program name) and renders (what the tests call; `--help`, which
/// the binary prints, is an error here).
pub fn run(args: &[String]) -> Result<Rendered, BoxError> {
    match Options::parse(args)? {
        Parsed::Run(options) => render(&options),
        Parsed::Help => Err(format!("--help renders nothing\n{}", usage_line(HELP)).into()),
    }
}

/// Renders the model as the [module docs](self) describe and writes the PNG and the EXR;
/// refused with [`WouldOverwriteInput`](crate::cli::WouldOverwriteInput) before anything is
/// read or written when one of them is an input file.
pub fn render(options: &Options) -> Result<Rendered, BoxError> {
    refuse_overwrite(&input_files(&options.model), &options.outputs())?;
    let meshes = volshadow::gltf::load(&options.model)?;
    let (lo, hi) = meshes
        .iter()
        .map(|m| world_bounds(m.transform, m.mesh.bounds()))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), (lo, hi)| {
            (a.min(lo), b.max(hi))
        });
    // In f64: a model 2e37 wide overflows f32's length (it was called "no extent").
    let (lo64, hi64) = (lo.as_dvec3(), hi.as_dvec3());
    let r64 = 0.5 * (hi64 - lo64).length();
    if r64.is_nan() || r64 <= 0.0 {
        return Err(format!("{}: the meshes have no extent", options.model.display()).into());
    }
    if r64 > 1e15 {
        return Err(format!(
            "{}: the meshes span {:e} units, beyond what the example frames in f32 (1e15); \
             scale the model",
            options.model.display(),
            2.0 * r64
        )
        .into());
    }
    let center = (0.5 * (lo64 + hi64)).as_vec3();
    let r = r64 as f32;
    println!(
        "{}: {} mesh(es), {} triangles, bounds {lo} .. {hi}",
        options.model.display(),
        meshes.len(),
        meshes
            .iter()
            .map(|m| m.mesh.triangle_count())
            .sum::<usize>()
    );
    let summaries: Vec<String> = meshes
        .iter()
        .enumerate()
        .map(|(i, m)| mesh_report(i, m))
        .collect();
    for line in &summaries {
        println!("{line}");
    }

    // Camera, ground, light and fog, all in units of r.
    let (width, height) = options.size;
    let camera = framing_camera((lo, hi), options.size)?;
    let ground = shapes::plane(Vec3::new(center.x, lo.y, center.z), Vec2::splat(12.0 * r)).unwrap();
    let light = Light::from(PointLight::new(
        center + r * Vec3::new(0.3, 1.0, -2.2),
        Vec3::new(1.0, 0.92, 0.8) * (40.0 * r * r),
    )?);
    let medium = Medium::new(
        Vec3::new(0.14, 0.15, 0.17) / r,
        Vec3::splat(0.01 / r),
        PhaseFunction::HenyeyGreenstein { g: 0.5 },
    )?;

    // The app's frame: the model and the ground.
    let gpu = HeadlessGpu::with_optional_features(wgpu::Features::TIMESTAMP_QUERY)?;
    println!("adapter: {}", gpu.adapter_summary());
    let mut objects = vec![DrawObject {
        mesh: &ground,
        transform: Mat4::IDENTITY,
        albedo: Vec3::splat(0.5),
    }];
    objects.extend(meshes.iter().map(|m| DrawObject {
        mesh: &m.mesh,
        transform: m.transform,
        albedo: Vec3::new(0.75, 0.7, 0.65),
    }));
    // Every mesh an occluder, uploaded once: for the surfaces' shadows and for volshadow.
    let uploaded: Vec<OccluderMesh> = meshes
        .iter()
        .map(|m| OccluderMesh::new(&gpu.device, &m.mesh))
        .collect();
    let occluders: Vec<Occluder> = uploaded
        .iter()
        .zip(&meshes)
        .map(|(mesh, m)| Occluder {
            mesh,
            transform: m.transform,
        })
        .collect();
    let maps = surface_shadow_maps(&gpu, &[light], &occluders, &camera)?;
    let draw_lights = [DrawLight {
        light,
        texture: None,
        shadow: maps[0].as_ref().and_then(|m| m.shadow_map()),
    }];
    let ambient = default_ambient(&camera, &draw_lights, &objects, &medium);
    let app = draw_app_frame(
        &gpu,
        &camera,
        options.size,
        &objects,
        &draw_lights,
        &medium,
        ambient,
    )?;

    // volshadow.
    let cache = Cache::new(&gpu.device);
    let settings = Settings {
        output_format: wgpu::TextureFormat::Rgba32Float,
        ..Settings::for_adapter(AdapterKind::of(&gpu.device))
    };
    let mut volumetric = VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, settings)?;
    let output = gpu.device.create_texture(&texture_desc(
        "output",
        options.size,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    ));
    let lights = [FrameLight::from(light)];
    let frame = Frame {
        camera: &camera,
        lights: &lights,
        medium: &medium,
        occluders: &occluders,
        scene_color: &app.color,
        scene_depth: &app.depth,
        surfaces: None,
    };
    let stats = render_frames(&gpu, &mut volumetric, &frame, &output)?;
    let radiance: Vec<DVec3> = gpu.read_rgba32f(&output)?.iter().map(rgb).collect();
    let inscatter = read_inscatter(&gpu, &volumetric, &frame)?;

    let (png, inscatter_exr) = (options.path(".png"), options.path(".inscatter.exr"));
    if let Some(dir) = png.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    write_png(
        &png,
        &tone_map(options.size, &radiance, auto_exposure(&radiance)),
    )?;
    write_exr(&inscatter_exr, options.size, &inscatter)?;
    println!(
        "wrote {} and {} ({width}x{height})",
        png.display(),
        inscatter_exr.display()
    );
    Ok(Rendered {
        png,
        inscatter_exr,
        summaries,
        inscatter,
        radiance,
        stats,
    })
}

/// The camera's vertical field of view.
pub const FOV_Y_DEGREES: f32 = 40.0;
/// The distance to the bounds' centre over the least distance at which their bounding sphere
/// fits the view: room around the model.
pub const FRAMING_MARGIN: f32 = 1.15;
/// The direction from the bounds' centre to the eye (front and slightly above: about 8.5°).
pub const VIEW_DIRECTION: Vec3 = Vec3::new(0.0, 0.15, 1.0);

/// The camera that frames the world bounds `(lo, hi)` in an image of `(width, height)`: it
/// looks at their centre along [`VIEW_DIRECTION`] from [`FRAMING_MARGIN`] times the distance at
/// which their bounding sphere (radius `r`, the half-diagonal) touches the view's inscribed
/// cone, whose half-angle is the smaller of the vertical half-FOV and the horizontal one
/// (`atan(aspect · tan(fov_y / 2))`): a portrait image is fitted by its width. Reversed-Z
/// infinite projection, near plane at `0.01 r`.
pub fn framing_camera(
    (lo, hi): (Vec3, Vec3),
    (width, height): (u32, u32),
) -> volshadow::Result<Camera> {
    let center = 0.5 * (lo + hi);
    let r = 0.5 * (hi - lo).length();
    let fov_y = FOV_Y_DEGREES.to_radians();
    let aspect = width as f32 / height as f32;
    let half_x = (aspect * (0.5 * fov_y).tan()).atan();
    let half = (0.5 * fov_y).min(half_x);
    let distance = FRAMING_MARGIN * r / half.sin();
    let eye = center + distance * VIEW_DIRECTION.normalize();
    Camera::new(
        volshadow::glam::camera::rh::view::look_at_mat4(eye, center, Vec3::Y),
        volshadow::glam::camera::rh::proj::directx::perspective_infinite_reverse(
            fov_y,
            aspect,
            0.01 * r,
        ),
    )
}

/// One mesh's topology and what it means for its shadow volume, e.g.
/// `mesh 0 "Box": 12 triangles, closed, 0 boundary and 0 non-manifold edges: ...`.
pub fn mesh_report(index: usize, mesh: &volshadow::gltf::GltfMesh) -> String {
    let s = mesh.mesh.summary();
    let name = mesh.name.as_deref().unwrap_or("(unnamed)");
    let meaning = if mesh.mesh.is_closed() {
        "only silhouette edges are extruded, so the shadow-volume extents \
         are tight"
    } else {
        "these edges are extruded as if always on the silhouette, so the shadow-volume \
         extents are conservative (they cover the shadow and more: correct, but more of each \
         ray is marched)"
    };
    let degenerate = if s.degenerate_triangles > 0 {
        format!(" ({} degenerate, ignored)", s.degenerate_triangles)
    } else {
        String::new()
    };
    format!(
        "mesh {index} {name:?}: {} triangles{degenerate}, {}, {} boundary and {} non-manifold \
         edges: {meaning}",
        s.triangles,
        match (mesh.mesh.is_closed(), s.boundary_edges) {
            (true, _) => "closed",
            (false, 0) => "non-manifold",
            (false, _) => "open",
        },
        s.boundary_edges,
        s.non_manifold_edges
    )
}

/// World-space bounds of an object-space box under `transform`.
fn world_bounds(transform: Mat4, (lo, hi): (Vec3, Vec3)) -> (Vec3, Vec3) {
    (0..8)
        .map(|k| {
            let pick = |bit: u32, a: f32, b: f32| if k & (1 << bit) == 0 { a } else { b };
            transform.transform_point3(Vec3::new(
                pick(0, lo.x, hi.x),
                pick(1, lo.y, hi.y),
                pick(2, lo.z, hi.z),
            ))
        })
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| {
            (a.min(p), b.max(p))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest |x| or |y| in normalised device coordinates of the 8 corners of `(lo, hi)`
    /// seen by `camera` (`INFINITY` when one is behind the eye): at most 1 when all are in view.
    fn worst_corner(camera: &Camera, (lo, hi): (Vec3, Vec3)) -> f32 {
        let clip_from_world = camera.projection() * camera.view();
        (0..8)
            .map(|k| {
                let pick = |bit: u32, a: f32, b: f32| if k & (1 << bit) == 0 { a } else { b };
                let corner = Vec3::new(
                    pick(0, lo.x, hi.x),
                    pick(1, lo.y, hi.y),
                    pick(2, lo.z, hi.z),
                );
                let clip = clip_from_world * corner.extend(1.0);
                if clip.w <= 0.0 {
                    f32::INFINITY
                } else {
                    (clip.x / clip.w).abs().max((clip.y / clip.w).abs())
                }
            })
            .fold(0.0, f32::max)
    }

    /// The framing before issue 36: the distance fitted to the vertical field of view alone.
    fn vertical_fit_camera((lo, hi): (Vec3, Vec3), (width, height): (u32, u32)) -> Camera {
        let (center, r) = (0.5 * (lo + hi), 0.5 * (hi - lo).length());
        let fov_y = FOV_Y_DEGREES.to_radians();
        let eye = center + 1.15 * r / (0.5 * fov_y).sin() * VIEW_DIRECTION.normalize();
        Camera::new(
            volshadow::glam::camera::rh::view::look_at_mat4(eye, center, Vec3::Y),
            volshadow::glam::camera::rh::proj::directx::perspective_infinite_reverse(
                fov_y,
                width as f32 / height as f32,
                0.01 * r,
            ),
        )
        .unwrap()
    }

    /// Every corner of the model's bounding box lands inside the image, whatever the model's
    /// proportions and the image's: landscape, square, portrait and narrow.
    #[test]
    fn gltf_framing_holds_the_bounding_box() {
        let models = [
            // The Stanford bunny as scanned (metres, off the origin), the remeshed one.
            (
                "bunny",
                Vec3::new(-0.0947, 0.0330, -0.0619),
                Vec3::new(0.0610, 0.1873, 0.0588),
            ),
            (
                "bunny (remeshed)",
                Vec3::new(-0.776, -0.769, -0.597),
                Vec3::new(0.776, 0.767, 0.599),
            ),
            ("cube", Vec3::splat(-1.0), Vec3::splat(1.0)),
            (
                "tower",
                Vec3::new(-1.0, 0.0, -1.0),
                Vec3::new(1.0, 30.0, 1.0),
            ),
            (
                "slab",
                Vec3::new(-50.0, 0.0, -1.0),
                Vec3::new(50.0, 2.0, 1.0),
            ),
        ];
        let sizes = [(800, 500), (512, 512), (500, 800), (300, 600), (200, 800)];
        let mut worst = (0.0f32, "", (0, 0));
        for (name, lo, hi) in models {
            for size in sizes {
                let camera = framing_camera((lo, hi), size).unwrap();
                let w = worst_corner(&camera, (lo, hi));
                assert!(w <= 1.0, "{name} at {size:?}: a corner at |NDC| {w:.3}");
                if w > worst.0 {
                    worst = (w, name, size);
                }
            }
        }
        println!(
            "gltf framing: the bounding boxes' corners reach |NDC| {:.3} at most ({} at {:?})",
            worst.0, worst.1, worst.2
        );
        // The earlier vertical-only fit: the default 800x500 held the bunny (|NDC| 0.63), a
        // narrow image did not.
        let bunny = (models[0].1, models[0].2);
        let old = worst_corner(&vertical_fit_camera(bunny, (800, 500)), bunny);
        let old_narrow = worst_corner(&vertical_fit_camera(bunny, (300, 600)), bunny);
        let cube = (models[2].1, models[2].2);
        let old_cube = worst_corner(&vertical_fit_camera(cube, (300, 600)), cube);
        println!(
            "vertical-only fit: bunny at 800x500 |NDC| {old:.3}, at 300x600 {old_narrow:.3}; \
             cube at 300x600 {old_cube:.3}"
        );
        assert!(old <= 1.0 && old_narrow > 1.0 && old_cube > 1.0);
    }
}
