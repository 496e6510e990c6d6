//! The spot light's surface term (the light the medium inside a spot's cone scatters onto a
//! Lambertian surface): the composite's `volshadow_iss_spot` against the f64 reference
//! `reference::surface_inscatter` (its own nested adaptive quadrature over the hemisphere, the
//! cone's own airlight along each direction; no code shared), and the reference against a
//! brute-force quadrature.
//!
//! The composite's cost with the term is measured by the ignored test `composite_cost`:
//!
//! ```text
//! cargo test --release --test gpu iss_spot::composite_cost -- --ignored --nocapture
//! ```
//!
//! (`VOLSHADOW_COST_SIZE=WxH` sets the frame, default 1920x1080 on a GPU and 256x144 on a CPU
//! adapter.)

use volshadow::nodes::{Encode, Node};
use volshadow_harness::rng;

use std::f64::consts::PI;
use std::sync::OnceLock;
use std::time::Instant;

use glam::{DVec3, Vec3};
use volshadow::nodes::{
    CompositeInputs, CompositeNode, CompositeSurfaces, IssTableNode, IssTableSize,
};
use volshadow::reference::{
    inscatter, surface_inscatter, surface_inscatter_cone, surface_inscatter_normalised,
    surface_inscatter_scale,
};
use volshadow::{
    Cache, Camera, HeadlessGpu, Light, Medium, PhaseFunction, ShaderPrecision, SpotLight,
};

/// A surface hit: point, the normal given to the composite, albedo ρ.
type Hit = (DVec3, DVec3, f64);

/// The inputs of a surface-term frame: depth, normals, albedo, a black scene colour.
struct SurfaceInputs {
    depth: wgpu::Texture,
    normal: wgpu::Texture,
    albedo: wgpu::Texture,
    black: wgpu::Texture,
    hits: Vec<Option<Hit>>,
}

fn surface_inputs(
    gpu: &HeadlessGpu,
    camera: &Camera,
    (width, height): (u32, u32),
    trace: &dyn Fn(DVec3, DVec3) -> Option<Hit>,
) -> SurfaceInputs {
    let hits: Vec<Option<Hit>> = (0..width * height)
        .map(|k| {
            let (eye, dir) =
                volshadow_harness::pixel_ray(camera, width, height, k % width, k / width);
            trace(eye, dir)
        })
        .collect();
    let depth: Vec<f32> = hits
        .iter()
        .map(|h| {
            h.map_or(camera.far_depth(), |(p, ..)| {
                volshadow_harness::ndc_depth(camera, p)
            })
        })
        .collect();
    let normal: Vec<[f32; 4]> = hits
        .iter()
        .map(|h| h.map_or([0.0; 4], |(_, n, _)| n.as_vec3().extend(0.0).to_array()))
        .collect();
    let albedo: Vec<[f32; 4]> = hits
        .iter()
        .map(|h| h.map_or([0.0; 4], |(.., a)| [a as f32, a as f32, a as f32, 1.0]))
        .collect();
    SurfaceInputs {
        depth: volshadow_harness::depth_texture(gpu, width, height, &depth),
        normal: volshadow_harness::rgba_texture(gpu, width, height, &normal),
        albedo: volshadow_harness::rgba_texture(gpu, width, height, &albedo),
        black: volshadow_harness::rgba_texture(
            gpu,
            width,
            height,
            &vec![[0.0; 4]; (width * height) as usize],
        ),
        hits,
    }
}

/// A built indirect single scattering table of the default size for `medium`.
fn table(gpu: &HeadlessGpu, cache: &Cache, medium: &Medium) -> IssTableNode {
    let mut table = IssTableNode::new(&gpu.device, cache, IssTableSize::default()).unwrap();
    table.prepare(&gpu.device, &gpu.queue, medium).unwrap();
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    table.encode(&mut encoder, None).unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    table
}

/// The composite's output (rgba) over a black scene with no in-scatter input, the surface term
/// of `lights` alone, with the spot term's lattice every `stride` pixels.
#[allow(clippy::too_many_arguments)]
fn surface_term_output(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    medium: &Medium,
    inputs: &SurfaceInputs,
    table: &IssTableNode,
    lights: &[Light],
    stride: u32,
) -> Vec<[f32; 4]> {
    let (width, height) = (inputs.depth.width(), inputs.depth.height());
    let output = volshadow_harness::texture(
        gpu,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        (width, height, 1),
        1,
    );
    let mut composite =
        CompositeNode::new(&gpu.device, cache, wgpu::TextureFormat::Rgba32Float).unwrap();
    composite.set_spot_lattice(stride).unwrap();
    let surfaces = CompositeSurfaces {
        normal: &inputs.normal,
        albedo: &inputs.albedo,
        table,
        lights,
    };
    let frame = CompositeInputs {
        camera,
        medium,
        scene_color: &inputs.black,
        scene_depth: &inputs.depth,
        inscatter: &[],
        surfaces: Some(&surfaces),
    };
    composite.prepare(&gpu.device, &gpu.queue, &frame).unwrap();
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    composite
        .encode(&mut encoder, &(&output).into(), None)
        .unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    let out = gpu.read_rgba32f(&output).unwrap();
    assert!(
        out.iter().flatten().all(|v| v.is_finite()),
        "a non-finite pixel"
    );
    out
}

/// The composite's output over a black scene with no in-scatter input: every pixel is the added
/// surface term `(ρ/π)·E(P)·exp(−σt·ds)` alone (red channel), at the default lattice.
fn surface_frame(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    medium: &Medium,
    light: Light,
    size: u32,
    trace: &dyn Fn(DVec3, DVec3) -> Option<Hit>,
) -> (Vec<f32>, Vec<Option<Hit>>) {
    let inputs = surface_inputs(gpu, camera, (size, size), trace);
    let table = table(gpu, cache, medium);
    let out = surface_term_output(
        gpu,
        cache,
        camera,
        medium,
        &inputs,
        &table,
        &[light],
        CompositeNode::DEFAULT_SPOT_LATTICE,
    );
    (out.iter().map(|p| p[0]).collect(), inputs.hits)
}

/// The reference added radiance of a hit seen from `eye`: `(ρ/π)·E(P)·exp(−σt·|P − eye|)`, red.
fn reference_added(eye: DVec3, hit: Hit, medium: &Medium, spot: &SpotLight) -> f64 {
    let (p, n, rho) = hit;
    let e = surface_inscatter_cone(p, n, medium, spot).x;
    rho / PI * e * (-f64::from(medium.sigma_t().x) * (p - eye).length()).exp()
}

/// The old model of the term (a point inside the cone gets the point light's whole term, a
/// point outside none), from the reference's `scale · G`: the "before" figures.
fn point_model_added(eye: DVec3, hit: Hit, medium: &Medium, spot: &SpotLight) -> f64 {
    let (p, n, rho) = hit;
    let apex = spot.position().as_dvec3();
    let rel = p - apex;
    let inside =
        spot.direction().as_dvec3().dot(rel) >= f64::from(spot.cos_half_angle()) * rel.length();
    if !inside {
        return 0.0;
    }
    let d = rel.length();
    let alpha = n.normalize().dot(-rel / d).clamp(-1.0, 1.0).acos();
    let scale = surface_inscatter_scale(medium, spot.intensity().as_dvec3(), d).x;
    let g =
        surface_inscatter_normalised(f64::from(medium.sigma_t().x) * d, alpha, &medium.phase()).x;
    rho / PI * scale * g * (-f64::from(medium.sigma_t().x) * (p - eye).length()).exp()
}

/// The `q` quantile of `v` (nearest rank; `v` non-empty).
fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let i = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    v[i]
}

/// The brute-force spot term: the midpoint rule over the sphere of directions about the
/// direction to the light (γ = π·u², which gathers cells towards the integrable peak there),
/// `nu × 2nu` cells, with `reference::inscatter` (the cone's own airlight, no occluders) along
/// each direction, times `(ω·n)₊`.
fn brute_force(p: DVec3, n: DVec3, medium: &Medium, spot: &SpotLight, nu: usize) -> f64 {
    let n = n.normalize();
    let l = (spot.position().as_dvec3() - p).normalize();
    let e1 = l.any_orthonormal_vector();
    let e2 = l.cross(e1);
    let nf = 2 * nu;
    let mut sum = 0.0;
    for i in 0..nu {
        let u = (i as f64 + 0.5) / nu as f64;
        let g = PI * u * u;
        let jac = 2.0 * PI * u * g.sin() / nu as f64 * (2.0 * PI / nf as f64);
        for j in 0..nf {
            let f = (j as f64 + 0.5) / nf as f64 * 2.0 * PI;
            let w = l * g.cos() + (e1 * f.cos() + e2 * f.sin()) * g.sin();
            let c = w.dot(n);
            if c > 0.0 {
                sum += inscatter(p, w, f64::INFINITY, medium, spot, &[]).x * c * jac;
            }
        }
    }
    sum
}

fn issue_medium() -> Medium {
    Medium::new(
        Vec3::splat(0.25),
        Vec3::splat(0.05),
        PhaseFunction::HenyeyGreenstein { g: 0.3 },
    )
    .unwrap()
}

/// The issue's spot: 60°, 1 above the floor `y = 0`, pointing straight down.
fn issue_spot() -> SpotLight {
    SpotLight::new(
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::NEG_Y,
        60f32.to_radians(),
        Vec3::splat(10.0),
    )
    .unwrap()
}

/// The reference's spot term (`surface_inscatter_cone`, and the general `surface_inscatter`,
/// 100–1000 times slower) against the brute-force midpoint rule (200 × 400 cells) at points on
/// the issue's floor on the axis, inside, just outside and well outside the cone, and at a
/// tilted point inside: within 2e-3. The bound: the midpoint
/// rule's own error, measured here by halving the cells (120 × 240 against 200 × 400 moves it
/// by at most 1.1e-3 at these points; the rule converges as the square of the cell size, so
/// 200 × 400 is within about 1e-3 of its limit).
#[test]
fn reference_spot_term_against_brute_force() {
    let medium = issue_medium();
    let spot = issue_spot();
    let points = [
        (DVec3::new(0.0, 0.0, 0.0), DVec3::Y),
        (DVec3::new(0.3, 0.0, 0.1), DVec3::Y),
        (DVec3::new(0.62, 0.0, 0.0), DVec3::Y),
        (DVec3::new(0.0, 0.0, 1.0), DVec3::Y),
        (DVec3::new(0.2, 0.3, 0.0), DVec3::new(1.0, 1.0, 0.0)),
    ];
    let mut worst = 0.0f64;
    for (p, n) in points {
        let t = Instant::now();
        let exact = surface_inscatter_cone(p, n, &medium, &spot).x;
        let elapsed = t.elapsed();
        let general = surface_inscatter(p, n, &medium, &spot).x;
        let coarse = brute_force(p, n, &medium, &spot, 120);
        let brute = brute_force(p, n, &medium, &spot, 200);
        let rel = (exact - brute).abs() / brute;
        eprintln!(
            "P {p}, n {n}: reference {exact:.6e} ({elapsed:.1?}; surface_inscatter {general:.6e}), \
             brute force {brute:.6e} (120 × 240: {coarse:.6e}, {:.1e} apart): {rel:.2e}",
            (coarse - brute).abs() / brute
        );
        worst = worst.max(rel).max((general - brute).abs() / brute);
    }
    assert!(worst <= 2e-3, "worst {worst:e}");
}

/// The issue's scene (a 60° spot 1 above a floor, HG 0.3, σs 0.25, σa 0.05) seen from above,
/// 40² pixels: the composite's added radiance against the reference per pixel, p95 of the
/// relative error inside the cone and on the band within 0.2 × the cone's radius outside it,
/// each at most 2% (the issue's bar). The old model's figures on the same pixels are printed
/// (the "before"), and its error on these pixels is checked to exceed the bar (so the test
/// tells the two apart).
fn issue_spot_scene(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let medium = issue_medium();
    let spot = issue_spot();
    let edge = (30f64).to_radians().tan();
    // Looking down from 2.6 above the floor, slightly off the axis: the floor out to about
    // 0.75 from it fills the view.
    let camera = volshadow_harness::look_at(Vec3::new(0.0, 2.6, 0.02), Vec3::ZERO, 32.0, 1.0);
    let floor = |eye: DVec3, dir: DVec3| {
        let t = -eye.y / dir.y;
        (t > 0.0).then(|| (eye + dir * t, DVec3::Y, 0.8))
    };
    let size = 40;
    let (out, hits) = surface_frame(&gpu, &cache, &camera, &medium, spot.into(), size, &floor);
    let eye = camera.eye().as_dvec3();
    let t = Instant::now();
    let (mut inside, mut band) = (Vec::new(), Vec::new());
    let (mut inside_before, mut band_before) = (Vec::new(), Vec::new());
    // Radial bins of 0.1 (signed mean errors, after and before).
    let mut bins = [[0.0f64; 3]; 8];
    for (k, hit) in hits.iter().enumerate() {
        let Some(hit) = *hit else { continue };
        let r = hit.0.x.hypot(hit.0.z);
        if r > 1.2 * edge {
            continue;
        }
        let exact = reference_added(eye, hit, &medium, &spot);
        let rel = (f64::from(out[k]) - exact) / exact;
        let before = (point_model_added(eye, hit, &medium, &spot) - exact) / exact;
        let bin = &mut bins[((r / 0.1) as usize).min(7)];
        *bin = [bin[0] + rel, bin[1] + before, bin[2] + 1.0];
        if r <= edge {
            inside.push(rel.abs());
            inside_before.push(before.abs());
        } else {
            band.push(rel.abs());
            band_before.push(before.abs());
        }
    }
    eprintln!(
        "{precision:?}: {} pixels inside, {} on the band; reference {:.1?}",
        inside.len(),
        band.len(),
        t.elapsed()
    );
    for (i, b) in bins.iter().enumerate().filter(|(_, b)| b[2] > 0.0) {
        eprintln!(
            "  r {:.1}–{:.1}: mean error {:+.3}% (before: {:+.1}%), {} pixels",
            0.1 * i as f64,
            0.1 * (i + 1) as f64,
            100.0 * b[0] / b[2],
            100.0 * b[1] / b[2],
            b[2]
        );
    }
    let p95 = [quantile(&mut inside, 0.95), quantile(&mut band, 0.95)];
    let before = [
        quantile(&mut inside_before, 0.95),
        quantile(&mut band_before, 0.95),
    ];
    let max = [quantile(&mut inside, 1.0), quantile(&mut band, 1.0)];
    eprintln!(
        "  p95 inside {:.3}% (max {:.3}%), band {:.3}% (max {:.3}%); before: p95 inside {:.1}%, band {:.1}%",
        100.0 * p95[0],
        100.0 * max[0],
        100.0 * p95[1],
        100.0 * max[1],
        100.0 * before[0],
        100.0 * before[1]
    );
    volshadow_harness::metric::accuracy(
        &format!("{precision:?}: a 60° spot 1 above a floor (HG 0.3, σt·D ≈ 0.3), 40²: the surface term against the f64 reference, p95 inside the cone; on the band within 0.2 × its radius outside; the point light's term cut at the cone (must fail)"),
        format!(
            "{:.3}%; {:.3}%; {:.1}% / {:.1}%",
            100.0 * p95[0],
            100.0 * p95[1],
            100.0 * before[0],
            100.0 * before[1]
        ),
        "2% each (the issue's); > 2%",
    );
    assert!(before[0] > 0.02 && before[1] > 0.02, "the old model passes");
    assert!(p95[0] <= 0.02 && p95[1] <= 0.02, "p95 {p95:?}");
}

volshadow_harness::at_each_precision!(
    issue_spot_scene => issue_spot_scene_native,
    issue_spot_scene_worst_case,
    [volshadow_harness::WORST_CASE]
);

/// The spot term's lattice (`CompositeNode::set_spot_lattice`) against the term evaluated at
/// every pixel, on the issue's spot over a floor with a wall, a ball and a rod a pixel or two
/// wide (silhouettes, a crease, a curved surface, the cone's edge; the rod's pixels lie between
/// lattice nodes on the floor, whose values agree), 320×180: at every pixel whose term is above 1%
/// of the frame's largest, the lattice's value within 0.5% of the evaluated one (a quarter of
/// the issue's 2% bar, so the quadrature's error and the lattice's together stay inside it),
/// at spacings 2 and 4. Prints the share of pixels that interpolate (the rest are evaluated).
#[test]
fn lattice_against_every_pixel() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let medium = issue_medium();
    let spot = issue_spot();
    // `VOLSHADOW_LATTICE_SIZE=WxH` measures another size (the share interpolated grows with it).
    let (width, height) = std::env::var("VOLSHADOW_LATTICE_SIZE")
        .ok()
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or((320u32, 180u32));
    let camera = volshadow_harness::look_at(
        Vec3::new(0.3, 1.4, 1.7),
        Vec3::new(0.0, 0.1, 0.0),
        60.0,
        width as f32 / height as f32,
    );
    let ball = (DVec3::new(0.25, 0.2, 0.15), 0.2);
    let trace = move |eye: DVec3, dir: DVec3| {
        let mut best: Option<Hit> = None;
        let mut near = f64::INFINITY;
        // The floor (y = 0) and a wall (x = −0.6).
        for (t, n) in [
            (-eye.y / dir.y, DVec3::Y),
            ((-0.6 - eye.x) / dir.x, DVec3::X),
        ] {
            let p = eye + dir * t;
            // (Each plane bounds the other; 1e-9 spares the plane's own rounding.)
            if t > 0.0 && t < near && p.x >= -0.6 - 1e-9 && p.y >= -1e-9 {
                near = t;
                best = Some((p, n, 0.8));
            }
        }
        // The rod: a vertical cylinder of radius 0.005 about (−0.1, y, 0.45), 0 ≤ y ≤ 0.5.
        let (axis_x, axis_z, r) = (-0.1, 0.45, 0.005);
        let (ox, oz) = (eye.x - axis_x, eye.z - axis_z);
        let a = dir.x * dir.x + dir.z * dir.z;
        let b = ox * dir.x + oz * dir.z;
        let disc = b * b - a * (ox * ox + oz * oz - r * r);
        if disc > 0.0 {
            let t = (-b - disc.sqrt()) / a;
            let p = eye + dir * t;
            if t > 0.0 && t < near && (0.0..=0.5).contains(&p.y) {
                near = t;
                best = Some((p, DVec3::new(p.x - axis_x, 0.0, p.z - axis_z) / r, 0.5));
            }
        }
        let oc = eye - ball.0;
        let b = oc.dot(dir);
        let disc = b * b - (oc.length_squared() - ball.1 * ball.1);
        if disc > 0.0 {
            let t = -b - disc.sqrt();
            if t > 0.0 && t < near {
                let p = eye + dir * t;
                best = Some((p, (p - ball.0) / ball.1, 0.6));
            }
        }
        best
    };
    let inputs = surface_inputs(&gpu, &camera, (width, height), &trace);
    let table = table(&gpu, &cache, &medium);
    let lights = [Light::from(spot)];
    let frame = |stride: u32| {
        surface_term_output(
            &gpu, &cache, &camera, &medium, &inputs, &table, &lights, stride,
        )
    };
    let every = frame(1);
    let max = every.iter().fold(0.0f32, |m, p| m.max(p[0]));
    assert!(max > 0.0, "the spot lights nothing");
    let mut failures = Vec::new();
    for stride in [2, 4] {
        let lattice = frame(stride);
        assert!(
            lattice.iter().flatten().all(|v| v.is_finite()),
            "non-finite"
        );
        let (mut counted, mut interpolated, mut worst) = (0usize, 0usize, (0.0f64, 0usize));
        for (k, (a, b)) in lattice.iter().zip(&every).enumerate() {
            if b[0] > 0.01 * max {
                counted += 1;
                interpolated += usize::from(a[..3] != b[..3]);
                let rel = (0..3)
                    .map(|c| f64::from((a[c] - b[c]).abs() / b[c]))
                    .fold(0.0, f64::max);
                if rel > worst.0 {
                    worst = (rel, k);
                }
            }
        }
        let share = interpolated as f64 / counted.max(1) as f64;
        eprintln!(
            "lattice every {stride} pixels, {width}x{height}: {:.1}% of {counted} lit pixels \
             interpolated; worst difference from every pixel evaluated {:.3}% at pixel ({}, {}) \
             ({:?}: {} against {})",
            100.0 * share,
            100.0 * worst.0,
            worst.1 as u32 % width,
            worst.1 as u32 / width,
            inputs.hits[worst.1],
            lattice[worst.1][0],
            every[worst.1][0]
        );
        volshadow_harness::metric::accuracy(
            &format!("the spot term's lattice every {stride} pixels against every pixel evaluated, floor, wall, ball and rod, {width}x{height}: worst difference; share of lit pixels interpolated"),
            format!("{:.3}%; {:.1}%", 100.0 * worst.0, 100.0 * share),
            "0.5% (a quarter of the issue's 2%)",
        );
        if worst.0 > 0.005 {
            failures.push(format!("lattice {stride}: worst {:.3}%", 100.0 * worst.0));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// One seeded spot scene: the light, the medium, a camera and a plane.
struct SpotScene {
    spot: SpotLight,
    medium: Medium,
    camera: Camera,
    plane: (DVec3, DVec3),
    describe: String,
}

/// Seed `seed`'s scene: apex angle 20°–120°, the light at distance D ∈ [1, 3] from a plane
/// point seen by the camera, which lies inside (seed % 3 = 0: up to 0.6 of the half angle off
/// the axis), across (1: 0.8–1.2) or outside (2: 1.1–1.5) the cone; σt·D ∈ [0.01, 5]
/// (log-uniform), σa/σt ∈ [0.05, 0.5], the phase isotropic, Rayleigh or Henyey–Greenstein
/// g ∈ [−0.3, 0.8]; the plane's normal turned up to 60° from the direction to the light, its
/// view 0.8·D across.
fn spot_scene(seed: u64) -> SpotScene {
    let mut rng = rng::Rng::new(seed);
    let apex = rng.range(20.0, 120.0);
    let half = (0.5 * apex).to_radians();
    let axis = rng.unit();
    let off = match seed % 3 {
        0 => rng.range(0.0, 0.6),
        1 => rng.range(0.8, 1.2),
        _ => rng.range(1.1, 1.5),
    } * half;
    let across = axis.any_orthonormal_vector();
    let across =
        (across * rng.range(-1.0, 1.0) + axis.cross(across) * rng.range(-1.0, 1.0)).normalize();
    let dir = axis * off.cos() + across * off.sin();
    let d = rng.range(1.0, 3.0);
    let light = rng.vec(-2.0, 2.0);
    let centre = light + dir * d;
    let to_light = -dir;
    let tilt = rng.range(0.0, 60f64.to_radians());
    let side = to_light.any_orthonormal_vector();
    let side =
        (side * rng.range(-1.0, 1.0) + to_light.cross(side) * rng.range(-1.0, 1.0)).normalize();
    let normal = to_light * tilt.cos() + side * tilt.sin();
    let tau = (rng.range(0.01f64.ln(), 5f64.ln())).exp();
    let sigma_t = tau / d;
    let absorb = rng.range(0.05, 0.5);
    let phase = match rng.range(0.0, 3.0) as u32 {
        0 => PhaseFunction::Isotropic,
        1 => PhaseFunction::Rayleigh,
        _ => PhaseFunction::HenyeyGreenstein {
            g: rng.range(-0.3, 0.8) as f32,
        },
    };
    let medium = Medium::new(
        Vec3::splat((sigma_t * (1.0 - absorb)) as f32),
        Vec3::splat((sigma_t * absorb) as f32),
        phase,
    )
    .unwrap();
    let spot = SpotLight::new(
        light.as_vec3(),
        axis.as_vec3(),
        apex.to_radians() as f32,
        Vec3::splat(10.0),
    )
    .unwrap();
    // The camera in front of the plane, at 1.5·D along a direction 0°–45° off its normal.
    let view_dir = (normal + side.cross(normal) * rng.range(-1.0, 1.0)).normalize();
    let eye = centre + view_dir * (1.5 * d);
    let fov = 2.0 * (0.4 * d / (1.5 * d)).atan();
    let camera = volshadow_harness::look_at(
        eye.as_vec3(),
        centre.as_vec3(),
        fov.to_degrees() as f32,
        1.0,
    );
    SpotScene {
        spot,
        medium,
        camera,
        plane: (centre, normal),
        describe: format!(
            "apex {apex:.0}°, off the axis {:.2} of the half angle, σt·D {tau:.3}, {phase:?}",
            off / half
        ),
    }
}

/// The seeded spot scenes: 24 seeds (8 each inside, across and outside the cone), 8² pixels
/// each (the f64 reference costs 4–28 ms a pixel in a release build, far more in the tests'
/// debug build: 16² took about ten minutes a precision on lavapipe's 2 cores), the composite against the reference at every pixel whose reference value is above 1%
/// of the frame's largest: the worst seed's p95 relative error at most 3% (the issue's bar).
/// Prints the failing seed.
fn seeded_spot_scenes(precision: ShaderPrecision) {
    const SEEDS: u64 = 24;
    /// Per seed, the reference's value at each pixel whose ray hits the plane (the rays are
    /// the camera's, the same at every precision).
    static SEEDED_REFERENCE: [OnceLock<Vec<(usize, f64)>>; SEEDS as usize] =
        [const { OnceLock::new() }; SEEDS as usize];
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let size = 8;
    let mut worst = (0.0f64, 0u64);
    let mut failures = Vec::new();
    // The two precisions' tests share each seed's reference (it depends on neither) and walk
    // the seeds from opposite ends, so that, run side by side, they split its cost.
    let seeds: Vec<u64> = match precision {
        ShaderPrecision::Native => (0..SEEDS).collect(),
        _ => (0..SEEDS).rev().collect(),
    };
    for seed in seeds {
        let scene = spot_scene(seed);
        let (centre, normal) = scene.plane;
        let trace = move |eye: DVec3, dir: DVec3| {
            let t = (centre - eye).dot(normal) / dir.dot(normal);
            (t > 0.0).then(|| (eye + dir * t, normal, 0.7))
        };
        let (out, hits) = surface_frame(
            &gpu,
            &cache,
            &scene.camera,
            &scene.medium,
            scene.spot.into(),
            size,
            &trace,
        );
        let eye = scene.camera.eye().as_dvec3();
        let values = SEEDED_REFERENCE[seed as usize].get_or_init(|| {
            hits.iter()
                .enumerate()
                .filter_map(|(k, h)| {
                    h.map(|h| (k, reference_added(eye, h, &scene.medium, &scene.spot)))
                })
                .collect()
        });
        let max = values.iter().fold(0.0f64, |m, v| m.max(v.1));
        let mut errors: Vec<f64> = values
            .iter()
            .filter(|v| v.1 > 0.01 * max)
            .map(|&(k, exact)| (f64::from(out[k]) - exact).abs() / exact)
            .collect();
        if errors.is_empty() {
            eprintln!("seed {seed}: {}: nothing lit", scene.describe);
            continue;
        }
        let n = errors.len();
        let p95 = quantile(&mut errors, 0.95);
        let top = quantile(&mut errors, 1.0);
        eprintln!(
            "seed {seed}: {}: {n} pixels, p95 {:.3}%, max {:.3}%",
            scene.describe,
            100.0 * p95,
            100.0 * top
        );
        if p95.is_nan() || p95 > worst.0 {
            worst = (p95, seed);
        }
        if p95.is_nan() || p95 > 0.03 {
            failures.push(format!("seed {seed}: p95 {:.2}%", 100.0 * p95));
        }
    }
    eprintln!(
        "{precision:?}: worst seed {} at p95 {:.3}%",
        worst.1,
        100.0 * worst.0
    );
    volshadow_harness::metric::accuracy(
        &format!("{precision:?}: 24 seeded spot scenes (apex 20°–120°, inside / across / outside the cone, σt·D 0.01–5), 8²: the surface term against the f64 reference, the worst seed's p95"),
        format!("{:.3}% (seed {})", 100.0 * worst.0, worst.1),
        "3% (the issue's)",
    );
    assert!(failures.is_empty(), "{failures:?}");
}

volshadow_harness::at_each_precision!(
    #[cfg_attr(not(feature = "sweeps"), ignore = "an accuracy sweep: --features sweeps")]
    seeded_spot_scenes => seeded_spot_scenes_native,
    seeded_spot_scenes_worst_case,
    [volshadow_harness::WORST_CASE]
);

/// Stiff spot cases, each a 12² frame of a wall: every pixel finite and non-negative, and the
/// p95 against the reference (pixels above 1% of the frame's largest) printed. The apex 0.01
/// from the wall (σt·D from 3e-3; the surface touches the light); σt·D ≈ 20 (I0 = 1e12 keeps
/// the radiance inside f32); normals facing away from the light; a 1° and a 179° cone; the
/// axis exactly along the wall's normal through the frame's centre. Asserted: finite, and
/// p95 within 3% where σt·D ≤ 5 (the range the quadrature is built for; the printed figure at
/// σt·D ≈ 20 characterises it beyond).
#[test]
#[ignore = "slow in the debug test build (the f64 reference at the stiff cases): cargo test --release --features gltf,image --test gpu iss_spot:: -- --ignored"]
fn stiff_spot_cases() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let wall = |eye: DVec3, dir: DVec3| {
        let t = (-2.0 - eye.z) / dir.z;
        (t > 0.0).then(|| (eye + dir * t, DVec3::Z, 0.7))
    };
    let facing_away = |eye: DVec3, dir: DVec3| wall(eye, dir).map(|(p, _, a)| (p, DVec3::NEG_Z, a));
    type Trace<'a> = &'a dyn Fn(DVec3, DVec3) -> Option<Hit>;
    // name, [σs, σa], apex, axis, apex angle (degrees), intensity, eye, surface, checked
    type Case<'a> = (
        &'a str,
        [f32; 2],
        Vec3,
        Vec3,
        f32,
        f32,
        Vec3,
        Trace<'a>,
        bool,
    );
    let cases: [Case<'_>; 6] = [
        (
            "touching the wall",
            [0.25, 0.05],
            Vec3::new(0.0, 0.0, -1.99),
            Vec3::NEG_Z,
            90.0,
            1.0,
            Vec3::new(0.0, 0.0, -1.2),
            &wall,
            true,
        ),
        (
            "σt·D ≈ 20",
            [8.0, 2.0],
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::NEG_Z,
            60.0,
            1e12,
            Vec3::new(0.0, 0.0, -1.5),
            &wall,
            false,
        ),
        (
            "facing away",
            [0.8, 0.2],
            Vec3::new(0.2, 0.1, -1.0),
            Vec3::new(0.1, 0.0, -1.0),
            70.0,
            5.0,
            Vec3::new(0.0, 0.0, 0.5),
            &facing_away,
            true,
        ),
        (
            "1° cone",
            [0.25, 0.05],
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::NEG_Z,
            1.0,
            10.0,
            Vec3::new(0.0, 0.0, 0.5),
            &wall,
            true,
        ),
        (
            "179° cone",
            [0.25, 0.05],
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 0.0),
            179.0,
            10.0,
            Vec3::new(0.0, 0.0, 0.5),
            &wall,
            true,
        ),
        (
            "axis along the normal",
            [0.5, 0.1],
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::NEG_Z,
            40.0,
            10.0,
            Vec3::new(0.0, 0.0, 1.0),
            &wall,
            true,
        ),
    ];
    let mut failures = Vec::new();
    for (name, [s, a], apex, axis, angle, intensity, eye, trace, checked) in cases {
        let medium = Medium::new(
            Vec3::splat(s),
            Vec3::splat(a),
            PhaseFunction::HenyeyGreenstein { g: 0.5 },
        )
        .unwrap();
        let spot = SpotLight::new(apex, axis, angle.to_radians(), Vec3::splat(intensity)).unwrap();
        let camera = volshadow_harness::look_at(eye, Vec3::new(0.0, 0.0, -2.0), 50.0, 1.0);
        let (out, hits) = surface_frame(&gpu, &cache, &camera, &medium, spot.into(), 12, trace);
        assert!(out.iter().all(|v| *v >= 0.0), "{name}: a negative pixel");
        let e = eye.as_dvec3();
        let values: Vec<(usize, f64)> = hits
            .iter()
            .enumerate()
            .filter_map(|(k, h)| h.map(|h| (k, reference_added(e, h, &medium, &spot))))
            .collect();
        let max = values.iter().fold(0.0f64, |m, v| m.max(v.1));
        let mut errors: Vec<f64> = values
            .iter()
            .filter(|v| v.1 > 0.01 * max)
            .map(|&(k, exact)| (f64::from(out[k]) - exact).abs() / exact)
            .collect();
        if errors.is_empty() {
            eprintln!("{name}: nothing lit");
            continue;
        }
        let p95 = quantile(&mut errors, 0.95);
        eprintln!(
            "{name}: {} pixels, p95 {:.3}%, max {:.3}%",
            errors.len(),
            100.0 * p95,
            100.0 * quantile(&mut errors, 1.0)
        );
        if checked && (p95.is_nan() || p95 > 0.03) {
            failures.push(format!("{name}: p95 {:.2}%", 100.0 * p95));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// The composite's cost on a spot scene with the surface term (the defaults: the facade's
/// table size, the compute composite) against the same frame without it and with a point
/// light's term instead. GPU time of the composite pass from timestamps on a GPU; on a CPU
/// adapter (whose timestamps do not bracket compute dispatches) the wall clock of the pass
/// submitted alone. Medians over 15 frames after 3 warm-up frames. Ignored: a measurement, not
/// a check (see the module docs for the command).
#[test]
#[ignore]
fn composite_cost() {
    let gpu = volshadow_harness::gpu_timed();
    let cpu = gpu.adapter.get_info().device_type == wgpu::DeviceType::Cpu;
    let (width, height) = std::env::var("VOLSHADOW_COST_SIZE")
        .ok()
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or(if cpu { (256, 144) } else { (1920, 1080) });
    eprintln!("adapter: {}", gpu.adapter_summary());
    let cache = volshadow_harness::cache(&gpu);
    let medium = issue_medium();
    let spot = issue_spot();
    let point = volshadow::PointLight::new(spot.position(), spot.intensity()).unwrap();
    // The issue's floor, seen at an angle: the cone's footprint and its surroundings fill it.
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 1.6, 1.6),
        Vec3::ZERO,
        60.0,
        width as f32 / height as f32,
    );
    let floor = |eye: DVec3, dir: DVec3| {
        let t = -eye.y / dir.y;
        (t > 0.0).then(|| (eye + dir * t, DVec3::Y, 0.8))
    };
    let inputs = surface_inputs(&gpu, &camera, (width, height), &floor);
    let table = table(&gpu, &cache, &medium);
    let output = volshadow_harness::texture(
        &gpu,
        wgpu::TextureFormat::Rgba16Float,
        wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT,
        (width, height, 1),
        1,
    );
    let mut results = Vec::new();
    let lattice = CompositeNode::DEFAULT_SPOT_LATTICE;
    for (name, light, stride) in [
        ("without the term", None, lattice),
        ("point light's term", Some(Light::from(point)), lattice),
        (
            "spot light's term, every pixel evaluated",
            Some(Light::from(spot)),
            1,
        ),
        (
            "spot light's term, lattice every 2 pixels",
            Some(Light::from(spot)),
            2,
        ),
        (
            "spot light's term, lattice every 4 pixels",
            Some(Light::from(spot)),
            4,
        ),
    ] {
        let mut composite =
            CompositeNode::new(&gpu.device, &cache, wgpu::TextureFormat::Rgba16Float).unwrap();
        composite.set_spot_lattice(stride).unwrap();
        let lights: Vec<Light> = light.into_iter().collect();
        let surfaces = CompositeSurfaces {
            normal: &inputs.normal,
            albedo: &inputs.albedo,
            table: &table,
            lights: &lights,
        };
        let frame = CompositeInputs {
            camera: &camera,
            medium: &medium,
            scene_color: &inputs.black,
            scene_depth: &inputs.depth,
            inscatter: &[],
            surfaces: (!lights.is_empty()).then_some(&surfaces),
        };
        composite.prepare(&gpu.device, &gpu.queue, &frame).unwrap();
        let mut times = Vec::new();
        for i in 0..18 {
            let mut timer = volshadow::gpu::GpuTimer::new(&gpu.device, &gpu.queue, 2);
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            composite
                .encode(
                    &mut encoder,
                    &(&output).into(),
                    (!cpu).then_some(&mut timer),
                )
                .unwrap();
            timer.resolve(&mut encoder);
            let t = Instant::now();
            gpu.submit_and_wait(encoder).unwrap();
            let wall = t.elapsed().as_secs_f64() * 1e3;
            let ms = if cpu {
                wall
            } else {
                timer.read(&gpu.device).unwrap().iter().map(|p| p.ms).sum()
            };
            if i >= 3 {
                times.push(ms);
            }
        }
        let median = quantile(&mut times, 0.5);
        eprintln!(
            "{width}x{height} composite, {name}: {median:.3} ms (p10 {:.3}, p90 {:.3}){}",
            quantile(&mut times, 0.1),
            quantile(&mut times, 0.9),
            if cpu {
                ", wall clock of the pass alone"
            } else {
                ", GPU timestamps"
            }
        );
        results.push(median);
    }
    eprintln!(
        "spot term adds {:.3} ms evaluated at every pixel, {:.3} ms with the lattice every 2, \
         {:.3} ms every 4 (the composite without it {:.3} ms; the point term adds {:.3} ms)",
        results[2] - results[0],
        results[3] - results[0],
        results[4] - results[0],
        results[0],
        results[1] - results[0]
    );
}
