//! The quickstart's scene (a point light behind two spheres in hazy air, over a ground) built
//! from Bevy entities and PBR materials, rendered headless to PNGs: once through volshadow, once
//! through Bevy's own `VolumetricFog` with the parameters mapped as closely as the two models
//! allow (see the plugin's README).
//!
//! `cargo run --release -p volshadow_bevy --example compare --ignore-rust-version` writes
//! `out/bevy_volshadow.png` and `out/bevy_fog.png`; `-- --size 480x270` sets the size,
//! `-- --mode volshadow` (or `bevy`) renders one of them. `-- --table --size 160x90` prints the
//! side-by-side table instead: each renderer's in-scatter (black surfaces, no tone mapping)
//! against volshadow's f64 reference, and its time per frame. `-- --first-frames` times the
//! first frames of a new app, with and without volshadow (the cold start).
//!
//! The scene itself, shared with the `window` example and `tests/compare.rs`, is the crate
//! `volshadow_bevy_scene` (`integrations/bevy/scene/`).

use bevy::math::Vec3;
use bevy::mesh::{Mesh, Meshable};
use bevy::render::view::Msaa;
use bevy::shape::Sphere;
use volshadow_bevy_scene::{
    render, Look, Mode, Rendered, EYE, FOV, G, LIGHT, LUMENS, NEAR, SIGMA_A, SIGMA_S, SPHERES,
    TARGET,
};

/// The scene's in-scatter in f64 (`volshadow::reference`), for [`Look::Inscatter`] images.
fn reference(width: u32, height: u32) -> (Vec<volshadow::glam::DVec3>, Vec<bool>) {
    use volshadow::glam::{camera::rh, DMat4, DVec3, Vec3 as V3};
    use volshadow::reference::{self, ImageError, Occluder, TriangleMesh};
    let v3 = |v: Vec3| V3::from_array(v.to_array());
    let view = rh::view::look_at_mat4(v3(EYE), v3(TARGET), V3::Y);
    let aspect = width as f32 / height as f32;
    let projection = rh::proj::directx::perspective_infinite_reverse(FOV, aspect, NEAR);
    let camera = volshadow::Camera::new(view, projection).unwrap();
    let mesh = Sphere::new(0.5).mesh().ico(4).unwrap();
    let positions: Vec<V3> = mesh
        .attribute(Mesh::ATTRIBUTE_POSITION)
        .unwrap()
        .as_float3()
        .unwrap()
        .iter()
        .map(|p| V3::from_array(*p))
        .collect();
    let indices: Vec<u32> = mesh.indices().unwrap().iter().map(|i| i as u32).collect();
    let spheres: Vec<TriangleMesh> = SPHERES
        .iter()
        .map(|&(x, y, z)| {
            let at = DMat4::from_translation(DVec3::new(x.into(), y.into(), z.into()));
            TriangleMesh::from_indexed(&positions, &indices, at)
        })
        .collect();
    let occluders: Vec<Occluder> = spheres.iter().cloned().map(Occluder::Mesh).collect();
    let exposure = bevy::camera::Exposure::default().exposure();
    let light = volshadow::PointLight::new(
        v3(LIGHT),
        V3::splat(LUMENS * exposure / (4.0 * std::f32::consts::PI)),
    )
    .unwrap();
    let medium = volshadow::Medium::new(
        V3::splat(SIGMA_S),
        V3::splat(SIGMA_A),
        volshadow::PhaseFunction::HenyeyGreenstein { g: G },
    )
    .unwrap();
    let distance = |eye: DVec3, dir: DVec3| {
        let ground = if dir.y < 0.0 {
            let t = -eye.y / dir.y;
            let p = eye + t * dir;
            if p.x.abs() <= 20.0 && p.z.abs() <= 20.0 {
                t
            } else {
                f64::INFINITY
            }
        } else {
            f64::INFINITY
        };
        spheres
            .iter()
            .map(|s| s.ray_distance(eye, dir))
            .fold(ground, f64::min)
    };
    let image = reference::inscatter_image(
        &camera, width, height, distance, &medium, &light, &occluders,
    );
    let keep = ImageError::keep_away_from_lights(&camera, &[light.into()], width, height);
    (image, keep)
}

/// Prints the side-by-side table: each renderer's error against the f64 reference and its
/// time per frame over `frames` back-to-back frames, at `width × height`.
fn table(width: u32, height: u32, frames: u32) {
    use volshadow::glam::DVec3;
    let (reference, keep) = reference(width, height);
    let adapter = {
        let r = Rendered::new(Mode::Plain, Look::Inscatter, Msaa::Off, 8, 8);
        r.gpu().adapter_summary()
    };
    println!(
        "{width}x{height}, {frames} frames each, {adapter}; Bevy's default 4× MSAA unless noted"
    );
    println!(
        "| renderer | p95 | RMSE | scaled by | p95 so scaled | ms per frame | ms over the plain scene |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut plain_ms = 0.0;
    for (mode, msaa) in [
        (Mode::Plain, Msaa::default()),
        (Mode::Volshadow, Msaa::default()),
        (Mode::Volshadow, Msaa::Off),
        (Mode::BevyFogSteps(64), Msaa::default()),
        (Mode::BevyFogSteps(256), Msaa::default()),
    ] {
        let mut rendered = Rendered::new(mode, Look::Inscatter, msaa, width, height);
        let pixels: Vec<DVec3> = bytemuck_f32(&rendered.bytes())
            .chunks_exact(4)
            .map(|p| DVec3::new(p[0].into(), p[1].into(), p[2].into()))
            .collect();
        let start = std::time::Instant::now();
        for _ in 0..frames {
            rendered.frame();
        }
        let ms = start.elapsed().as_secs_f64() * 1e3 / f64::from(frames);
        let name = match mode {
            Mode::Plain => {
                plain_ms = ms;
                println!("| the scene without a medium | – | – | – | – | {ms:.1} | – |");
                continue;
            }
            Mode::Volshadow if msaa == Msaa::Off => "volshadow, MSAA off".to_string(),
            Mode::Volshadow => "volshadow (plugin defaults: error target 1%; 4× MSAA)".to_string(),
            _ => format!(
                "Bevy VolumetricFog, {} steps",
                mode.bevy_steps().unwrap_or(64)
            ),
        };
        let error = volshadow::reference::ImageError::measure(&pixels, &reference, &keep);
        // The one brightness factor that brings the image closest to the reference (least
        // squares over the kept pixels): what is left is the shape of the light and shadows.
        let kept = || {
            pixels
                .iter()
                .zip(&reference)
                .zip(&keep)
                .filter(|(_, k)| **k)
                .map(|(pr, _)| pr)
        };
        let scale = kept().map(|(p, r)| p.dot(*r)).sum::<f64>()
            / kept()
                .map(|(p, _)| p.dot(*p))
                .sum::<f64>()
                .max(f64::MIN_POSITIVE);
        let scaled: Vec<DVec3> = pixels.iter().map(|p| *p * scale).collect();
        let shape = volshadow::reference::ImageError::measure(&scaled, &reference, &keep);
        println!(
            "| {name} | {:.2}% | {:.2}% | {scale:.3} | {:.2}% | {ms:.1} | {:.1} |",
            100.0 * error.p95,
            100.0 * error.rmse,
            100.0 * shape.p95,
            ms - plain_ms
        );
    }
}

/// Prints the time of each of the first frames of a new app, with and without volshadow, and
/// the median of later ones: what a cold start costs (pipelines compile synchronously in these
/// headless apps, Bevy's own as well as volshadow's).
fn first_frames(width: u32, height: u32) {
    const FIRST: usize = 4;
    const LATER: usize = 20;
    let adapter = {
        let r = Rendered::unrendered(Mode::Plain, Look::Picture, Msaa::Off, 8, 8);
        r.gpu().adapter_summary()
    };
    println!("{width}x{height}, Bevy's default 4× MSAA, {adapter}");
    println!(
        "| app | frame 1 ms | frame 2 | frame 3 | frame 4 | later frame (median of frames {}–{}) |",
        FIRST + LATER + 1,
        FIRST + 2 * LATER
    );
    println!("|---|---|---|---|---|---|");
    for mode in [Mode::Plain, Mode::Volshadow] {
        let mut rendered =
            Rendered::unrendered(mode, Look::Picture, Msaa::default(), width, height);
        let mut time = || {
            let start = std::time::Instant::now();
            rendered.frame();
            start.elapsed().as_secs_f64() * 1e3
        };
        let first: Vec<f64> = (0..FIRST).map(|_| time()).collect();
        // Frames 5 to 24 unmeasured: what warms in the background has finished by then.
        (0..LATER).for_each(|_| {
            time();
        });
        let mut later: Vec<f64> = (0..LATER).map(|_| time()).collect();
        later.sort_by(f64::total_cmp);
        let name = match mode {
            Mode::Plain => "the scene without a medium",
            _ => "volshadow (plugin defaults)",
        };
        let cells: Vec<String> = first.iter().map(|ms| format!("{ms:.0}")).collect();
        println!(
            "| {name} | {} | {:.1} |",
            cells.join(" | "),
            later[LATER / 2]
        );
    }
}

fn bytemuck_f32(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let (width, height) = value("--size")
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or((960, 540));
    let modes = match value("--mode").as_deref() {
        Some("volshadow") => vec![Mode::Volshadow],
        Some("bevy") => vec![Mode::BevyFog],
        _ => vec![Mode::Volshadow, Mode::BevyFog],
    };
    if args.iter().any(|a| a == "--first-frames") {
        first_frames(width, height);
        return;
    }
    if args.iter().any(|a| a == "--table") {
        let frames = value("--frames").and_then(|f| f.parse().ok()).unwrap_or(20);
        table(width, height, frames);
        return;
    }
    std::fs::create_dir_all("out").expect("create out/");
    for mode in modes {
        let pixels = render(mode, width, height);
        let path = match mode {
            Mode::Volshadow => "out/bevy_volshadow.png",
            _ => "out/bevy_fog.png",
        };
        image::RgbaImage::from_raw(width, height, pixels)
            .expect("pixels of the target's size")
            .save(path)
            .expect("write the PNG");
        println!("{mode:?}: {path} ({width}x{height})");
    }
}
