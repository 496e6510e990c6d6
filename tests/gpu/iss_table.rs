//! The indirect single scattering table (`nodes::IssTableNode`) read back and compared with the
//! f64 reference `reference::surface_inscatter_normalised` (its own adaptive quadrature, no code
//! shared): entries over σt·D ∈ [1e-3, 50], α ∈ [0, π], isotropic, Henyey–Greenstein 0.8 and
//! Rayleigh phases, and the bilinear interpolation of the default table between entries.

use volshadow::nodes::{Encode, Node};

use std::f64::consts::PI;
use std::time::Instant;

use glam::{DVec3, Vec3};
use volshadow::nodes::{
    CompositeInputs, CompositeNode, CompositeSurfaces, IssTableNode, IssTableSize, ISS_TAU_RANGE,
};
use volshadow::reference::{
    surface_inscatter, surface_inscatter_normalised, surface_inscatter_scale,
};
use volshadow::{
    Cache, Camera, HeadlessGpu, Light, Medium, PhaseFunction, PointLight, ShaderPrecision,
};

const PHASES: [(&str, PhaseFunction); 3] = [
    ("isotropic", PhaseFunction::Isotropic),
    ("HG 0.8", PhaseFunction::HenyeyGreenstein { g: 0.8 }),
    ("Rayleigh", PhaseFunction::Rayleigh),
];

/// The checked range of the optical distance σt·D.
const TAU: [f64; 2] = [1e-3, 50.0];

/// `(τ, α)` of table coordinates `(u, v)`, the axes `nodes::IssTableNode` documents, in f64.
fn point(u: f64, v: f64) -> (f64, f64) {
    let [lo, hi] = ISS_TAU_RANGE.map(f64::from);
    let tau = lo * (u * (hi / lo).ln()).exp();
    let s = 4.0 + tau;
    let cos = (((1.0 - 2.0 * v) * s.asinh()).sinh() / s).clamp(-1.0, 1.0);
    (tau, cos.acos())
}

/// Builds a table of `size` for `phase` and reads it back (ln G per channel).
fn build(
    gpu: &HeadlessGpu,
    cache: &Cache,
    size: IssTableSize,
    phase: PhaseFunction,
) -> Vec<[f32; 4]> {
    let medium = Medium::new(Vec3::splat(0.5), Vec3::splat(0.1), phase).unwrap();
    let mut node = IssTableNode::new(&gpu.device, cache, size).unwrap();
    assert!(
        node.prepare(&gpu.device, &gpu.queue, &medium).unwrap(),
        "a fresh table is built"
    );
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    node.encode(&mut encoder, None).unwrap();
    let t = Instant::now();
    gpu.submit_and_wait(encoder).unwrap();
    eprintln!(
        "  {phase:?}: {}×{} table built in {:.0?}",
        size.tau,
        size.alpha,
        t.elapsed()
    );
    // Unchanged medium: nothing to rebuild.
    assert!(!node.prepare(&gpu.device, &gpu.queue, &medium).unwrap());
    gpu.read_rgba32f(node.texture()).unwrap()
}

volshadow_harness::at_each_precision!(
    entries_match_the_reference_at => entries_match_the_reference,
    entries_match_the_reference_worst_case,
    [volshadow_harness::WORST_CASE]
);

/// The table's entries against the reference: within 1e-3 relative wherever G is above 1e-6 of
/// its maximum over the checked nodes (the bar the table must meet), every entry finite. A
/// 33 × 65 table's nodes are checked where σt·D ∈ [1e-3, 50]: every other τ node, and every
/// α node in the sixth of the axis about α = π/2 (where G falls over ~1/τ) and every third
/// elsewhere.
/// The `_worst_case` test: the same with every transcendental built-in off by the most WGSL
/// allows.
fn entries_match_the_reference_at(precision: ShaderPrecision) {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache_with(&gpu, precision);
    let size = IssTableSize { tau: 33, alpha: 65 };
    let (nu, nv) = (size.tau as usize, size.alpha as usize);
    let mut failures = Vec::new();
    for (name, phase) in PHASES {
        let table = build(&gpu, &cache, size, phase);
        assert!(
            table.iter().flatten().all(|v| v.is_finite()),
            "{name}: a non-finite entry"
        );
        let t = Instant::now();
        let mut checked = Vec::new();
        for j in 0..nv {
            let v = j as f64 / (nv - 1) as f64;
            if !((v - 0.5).abs() <= 1.0 / 12.0 || j % 3 == 0 || j == nv - 1) {
                continue;
            }
            for i in (0..nu).filter(|i| i % 2 == 0) {
                let (tau, alpha) = point(i as f64 / (nu - 1) as f64, v);
                if !(TAU[0]..=TAU[1]).contains(&tau) {
                    continue;
                }
                let exact = surface_inscatter_normalised(tau, alpha, &phase).x;
                let gpu = f64::from(table[j * nu + i][0]).exp();
                checked.push((exact, gpu, tau, alpha));
            }
        }
        let max = checked.iter().fold(0.0f64, |m, c| m.max(c.0));
        let mut worst = (0.0f64, 0.0, 0.0);
        for &(exact, gpu, tau, alpha) in checked.iter().filter(|c| c.0 > 1e-6 * max) {
            let rel = (gpu - exact).abs() / exact;
            if rel.is_nan() || rel > worst.0 {
                worst = (rel, tau, alpha);
            }
        }
        eprintln!(
            "{precision:?}: {name}: {} entries, max relative error {:.2e} (at τ {:.3e}, α {:.4}); reference {:.1?}",
            checked.len(),
            worst.0,
            worst.1,
            worst.2,
            t.elapsed()
        );
        volshadow_harness::metric::accuracy(
            &format!("{precision:?}: ISS table (33 × 65) entries against the f64 reference, σt·D 1e-3…50, {name}"),
            format!("max {:.1e} ({} entries)", worst.0, checked.len()),
            "1e-3 where G > 1e-6 of its maximum",
        );
        if worst.0.is_nan() || worst.0 > 1e-3 {
            failures.push(format!("{name}: {:.2e}", worst.0));
        }
    }
    assert!(
        failures.is_empty(),
        "{precision:?}: entries off by more than 1e-3: {failures:?}"
    );
}

/// The default table ([`IssTableSize::default`], 96 × 128) between its entries: `ln G`
/// interpolated bilinearly (as `ISS_WGSL`'s lookup does, in f32) at the centres of its cells
/// where σt·D ∈ [1e-3, 50] (every third cell in τ, every fourth in α, and every cell in the
/// twelfth of the α axis about π/2): within 1e-3 relative wherever G is above 1e-6 of the
/// maximum. This is the table's accuracy as a caller's shader sees it (measured 5–6e-4; 48 × 192
/// gives 2.1–2.5e-3, 96 × 96 up to 9.4e-4: the τ axis sets the size).
#[test]
fn default_table_interpolates_within_1e_3() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let size = IssTableSize::default();
    let (nu, nv) = (size.tau as usize, size.alpha as usize);
    let mut failures = Vec::new();
    for (name, phase) in PHASES {
        let table = build(&gpu, &cache, size, phase);
        let at = |i: usize, j: usize| table[j * nu + i][0];
        let mut checked = Vec::new();
        for j in 0..nv - 1 {
            let v = (j as f64 + 0.5) / (nv - 1) as f64;
            if !((v - 0.5).abs() <= 1.0 / 24.0 || j % 4 == 0) {
                continue;
            }
            for i in (0..nu - 1).filter(|i| i % 3 == 0) {
                let (tau, alpha) = point((i as f64 + 0.5) / (nu - 1) as f64, v);
                if !(TAU[0]..=TAU[1]).contains(&tau) {
                    continue;
                }
                let mixed = 0.25 * (at(i, j) + at(i + 1, j) + at(i, j + 1) + at(i + 1, j + 1));
                let exact = surface_inscatter_normalised(tau, alpha, &phase).x;
                checked.push((exact, f64::from(mixed.exp()), tau, alpha));
            }
        }
        let max = checked.iter().fold(0.0f64, |m, c| m.max(c.0));
        let mut worst = (0.0f64, 0.0, 0.0);
        for &(exact, gpu, tau, alpha) in checked.iter().filter(|c| c.0 > 1e-6 * max) {
            let rel = (gpu - exact).abs() / exact;
            if rel.is_nan() || rel > worst.0 {
                worst = (rel, tau, alpha);
            }
        }
        eprintln!(
            "{name}: {} cell centres, max relative error {:.2e} (at τ {:.3e}, α {:.4})",
            checked.len(),
            worst.0,
            worst.1,
            worst.2
        );
        volshadow_harness::metric::accuracy(
            &format!("the default ISS table ({} × {}) interpolated at cell centres, σt·D 1e-3…50, {name}", size.tau, size.alpha),
            format!("max {:.1e} ({} cells)", worst.0, checked.len()),
            "1e-3 where G > 1e-6 of its maximum",
        );
        if worst.0.is_nan() || worst.0 > 1e-3 {
            failures.push(format!("{name}: {:.2e}", worst.0));
        }
    }
    assert!(
        failures.is_empty(),
        "interpolation off by more than 1e-3: {failures:?}"
    );
}

/// A surface hit: point, the normal given to the composite, albedo ρ.
type Hit = (DVec3, DVec3, f64);

/// A pixel's surface from its ray (eye, direction).
type Trace<'a> = &'a dyn Fn(DVec3, DVec3) -> Option<Hit>;

/// A stiff case: name, `[σs, σa, g]`, light position, intensity, eye, the surface.
type Stiff<'a> = (&'a str, [f32; 3], Vec3, f32, Vec3, Trace<'a>);

/// The composite's output over a black scene with no in-scatter input, so every pixel is the
/// added surface term `(ρ/π)·E(P)·exp(−σt·ds)` alone. `trace` gives each pixel's surface.
#[allow(clippy::too_many_arguments)]
fn surface_frame(
    gpu: &HeadlessGpu,
    cache: &Cache,
    table: &IssTableNode,
    camera: &Camera,
    medium: &Medium,
    light: Light,
    size: u32,
    trace: impl Fn(DVec3, DVec3) -> Option<Hit>,
) -> (Vec<[f32; 4]>, Vec<Option<Hit>>) {
    let hits: Vec<Option<Hit>> = (0..size * size)
        .map(|k| {
            let (eye, dir) = volshadow_harness::pixel_ray(camera, size, size, k % size, k / size);
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
    let depth = volshadow_harness::depth_texture(gpu, size, size, &depth);
    let normal = volshadow_harness::rgba_texture(gpu, size, size, &normal);
    let albedo = volshadow_harness::rgba_texture(gpu, size, size, &albedo);
    let black =
        volshadow_harness::rgba_texture(gpu, size, size, &vec![[0.0; 4]; (size * size) as usize]);
    let output = volshadow_harness::texture(
        gpu,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        (size, size, 1),
        1,
    );
    let mut composite =
        CompositeNode::new(&gpu.device, cache, wgpu::TextureFormat::Rgba32Float).unwrap();
    let lights = [light];
    let surfaces = CompositeSurfaces {
        normal: &normal,
        albedo: &albedo,
        table,
        lights: &lights,
    };
    let inputs = CompositeInputs {
        camera,
        medium,
        scene_color: &black,
        scene_depth: &depth,
        inscatter: &[],
        surfaces: Some(&surfaces),
    };
    composite.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    composite
        .encode(&mut encoder, &(&output).into(), None)
        .unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    (gpu.read_rgba32f(&output).unwrap(), hits)
}

/// The reference added radiance of a hit seen from `eye`: `(ρ/π)·E(P)·exp(−σt·|P − eye|)`,
/// `E` as `scale · G` (equal to the world-space hemisphere integral `surface_inscatter` within
/// 1e-9, stiff cases included: `tests/cpu/reference_iss.rs`; that one is ten times slower).
fn reference_added(eye: DVec3, hit: Hit, medium: &Medium, light: &PointLight) -> f64 {
    let (p, n, rho) = hit;
    let to_light = light.position().as_dvec3() - p;
    let d = to_light.length();
    let alpha = n.normalize().dot(to_light / d).clamp(-1.0, 1.0).acos();
    let scale = surface_inscatter_scale(medium, light.intensity().as_dvec3(), d).x;
    let tau = f64::from(medium.sigma_t().x) * d;
    let e = scale * surface_inscatter_normalised(tau, alpha, &medium.phase()).x;
    rho / PI * e * (-f64::from(medium.sigma_t().x) * (p - eye).length()).exp()
}

/// Ground `y = 0` (normal +y) and a wall `z = −2` (normal +z), whichever the ray meets first.
fn ground_and_wall(eye: DVec3, dir: DVec3) -> Option<Hit> {
    let mut best: Option<(f64, Hit)> = None;
    for (n, offset, rho) in [(DVec3::Y, 0.0, 0.8), (DVec3::Z, -2.0, 0.5)] {
        let t = (offset - eye.dot(n)) / dir.dot(n);
        if t > 0.0 && best.is_none_or(|b| t < b.0) {
            best = Some((t, (eye + dir * t, n, rho)));
        }
    }
    best.map(|(_, h)| h)
}

/// Per-pixel relative error of the GPU's added radiance over the pixels (of `pixels`) whose
/// reference value is above 1% of the frame's largest; every GPU value must be finite.
fn frame_error(
    name: &str,
    out: &[[f32; 4]],
    hits: &[Option<Hit>],
    pixels: impl Iterator<Item = usize>,
    eye: DVec3,
    medium: &Medium,
    light: &PointLight,
) -> f64 {
    assert!(
        out.iter().flatten().all(|v| v.is_finite()),
        "{name}: a non-finite pixel"
    );
    let values: Vec<(usize, f64)> = pixels
        .filter_map(|k| hits[k].map(|h| (k, reference_added(eye, h, medium, light))))
        .collect();
    let max = values.iter().fold(0.0f64, |m, v| m.max(v.1));
    let mut worst = (0.0f64, 0usize, 0.0f64);
    let mut count = 0;
    for &(k, exact) in values.iter().filter(|v| v.1 > 0.01 * max) {
        count += 1;
        let rel = (f64::from(out[k][0]) - exact).abs() / exact;
        if rel.is_nan() || rel > worst.0 {
            worst = (rel, k, exact);
        }
    }
    eprintln!(
        "{name}: {count} pixels above 1% of the max ({max:.3e}); worst relative error {:.2e} \
         (pixel {}, reference {:.3e})",
        worst.0, worst.1, worst.2
    );
    worst.0
}

/// A 128² frame: ground and a wall near a point light in fog (HG 0.6), normals and albedo
/// given, the added radiance of the composite against the f64 reference per pixel where it is
/// above 1% of its maximum: within 1%. The reference costs ~10 ms a pixel, so every fourth
/// pixel in each direction is checked (1024 pixels, both surfaces, the light's neighbourhood
/// included). The table has the facade's default size (interpolation included).
#[test]
fn frame_of_ground_and_wall_matches_the_reference() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let medium = Medium::new(
        Vec3::splat(0.3),
        Vec3::splat(0.05),
        PhaseFunction::HenyeyGreenstein { g: 0.6 },
    )
    .unwrap();
    let mut table = IssTableNode::new(&gpu.device, &cache, IssTableSize::default()).unwrap();
    table.prepare(&gpu.device, &gpu.queue, &medium).unwrap();
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    table.encode(&mut encoder, None).unwrap();
    let t = Instant::now();
    gpu.submit_and_wait(encoder).unwrap();
    eprintln!("default table built in {:.0?}", t.elapsed());
    let camera = volshadow_harness::look_at(
        Vec3::new(0.3, 1.5, 4.0),
        Vec3::new(0.0, 0.6, -1.0),
        60.0,
        1.0,
    );
    let light = PointLight::new(Vec3::new(0.4, 0.9, -1.5), Vec3::new(20.0, 20.0, 20.0)).unwrap();
    let size = 128;
    let (out, hits) = surface_frame(
        &gpu,
        &cache,
        &table,
        &camera,
        &medium,
        light.into(),
        size,
        ground_and_wall,
    );
    let eye = camera.eye().as_dvec3();
    let pixels = (0..(size * size) as usize).filter(|k| (k % 128) % 4 == 1 && (k / 128) % 4 == 1);
    let t = Instant::now();
    let worst = frame_error(
        "128² ground and wall",
        &out,
        &hits,
        pixels,
        eye,
        &medium,
        &light,
    );
    eprintln!("  reference {:.1?}", t.elapsed());
    volshadow_harness::metric::accuracy(
        "128² ground and wall near a point light, HG 0.6: the composite's surface term against the reference (every 4th pixel)",
        format!("max {worst:.1e}"),
        "1e-2 where above 1% of the frame's maximum",
    );
    // Sky pixels get nothing.
    assert!(hits
        .iter()
        .zip(&out)
        .all(|(h, o)| h.is_some() || o[0] == 0.0));
    assert!(worst <= 0.01, "worst relative error {worst:e} > 1%");
}

/// Stiff cases, each a 24² frame of a wall checked against the reference at every pixel above
/// 1% of the maximum: within 1%, every pixel finite. A light
/// 0.01 from the wall (σt·D from 3e-3: the surface touches the light); σt·D ≈ 100 across the
/// frame (I0 = 1e30 keeps the radiance inside f32); and normals facing away from the light.
#[test]
fn stiff_cases_match_the_reference() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let wall = |eye: DVec3, dir: DVec3| {
        let t = (-2.0 - eye.z) / dir.z;
        (t > 0.0).then(|| (eye + dir * t, DVec3::Z, 0.7))
    };
    let facing_away = |eye: DVec3, dir: DVec3| wall(eye, dir).map(|(p, _, a)| (p, DVec3::NEG_Z, a));
    let size = 24;
    let cases: [Stiff<'_>; 3] = [
        (
            "touching the light",
            [0.25, 0.05, 0.5],
            Vec3::new(0.0, 0.0, -1.99),
            1.0,
            Vec3::new(0.0, 0.0, -1.2),
            &wall,
        ),
        (
            "σt·D = 100",
            [40.0, 10.0, 0.5],
            Vec3::new(0.0, 0.0, 0.0),
            1e30,
            Vec3::new(0.0, 0.0, -1.8),
            &wall,
        ),
        (
            "facing away",
            [0.8, 0.2, 0.5],
            Vec3::new(0.2, 0.1, -1.0),
            5.0,
            Vec3::new(0.0, 0.0, 0.5),
            &facing_away,
        ),
    ];
    let mut failures = Vec::new();
    let mut table = IssTableNode::new(&gpu.device, &cache, IssTableSize::default()).unwrap();
    for (name, [s, a, g], light_pos, intensity, eye, trace) in cases {
        let medium = Medium::new(
            Vec3::splat(s),
            Vec3::splat(a),
            PhaseFunction::HenyeyGreenstein { g },
        )
        .unwrap();
        // The table depends only on the phase function (HG 0.5 in every case): built once.
        if table.prepare(&gpu.device, &gpu.queue, &medium).unwrap() {
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            table.encode(&mut encoder, None).unwrap();
            gpu.submit_and_wait(encoder).unwrap();
        }
        let camera = volshadow_harness::look_at(eye, Vec3::new(0.0, 0.0, -2.0), 50.0, 1.0);
        let light = PointLight::new(light_pos, Vec3::splat(intensity)).unwrap();
        let (out, hits) = surface_frame(
            &gpu,
            &cache,
            &table,
            &camera,
            &medium,
            light.into(),
            size,
            trace,
        );
        let d = hits
            .iter()
            .flatten()
            .map(|h| (light_pos.as_dvec3() - h.0).length() * f64::from(s + a))
            .fold([f64::INFINITY, 0.0], |m, t| [m[0].min(t), m[1].max(t)]);
        eprintln!("{name}: σt·D from {:.2e} to {:.2e}", d[0], d[1]);
        let all = 0..(size * size) as usize;
        let worst = frame_error(name, &out, &hits, all, eye.as_dvec3(), &medium, &light);
        volshadow_harness::metric::accuracy(
            &format!("stiff case, {size}² wall, {name}: the surface term against the reference"),
            format!("max {worst:.1e} (σt·D {:.1e}…{:.1e})", d[0], d[1]),
            "1e-2 where above 1% of the frame's maximum",
        );
        if worst.is_nan() || worst > 0.01 {
            failures.push(format!("{name}: {worst:.2e}"));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// The planner: the ISS table runs (and the composite adds the term) only with surfaces given
/// and a scattering medium, is left out with the reason otherwise, and is not rebuilt while the
/// medium's phase function stays the same. The term reaches the output: a surface pixel in
/// front of the light brightens.
#[test]
fn planner_runs_the_table_only_with_surfaces_and_scattering() {
    use volshadow::plan::{Pass, Reason};
    use volshadow::{Frame, Settings, Surfaces, VolumetricShadows};
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let size = 16;
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(0.0, 0.0, -2.0),
        50.0,
        1.0,
    );
    let fog = Medium::new(
        Vec3::splat(0.3),
        Vec3::splat(0.05),
        PhaseFunction::Isotropic,
    )
    .unwrap();
    let clear = Medium::new(Vec3::ZERO, Vec3::splat(0.05), PhaseFunction::Isotropic).unwrap();
    let lights =
        [
            Light::from(PointLight::new(Vec3::new(0.0, 0.0, -1.5), Vec3::splat(5.0)).unwrap())
                .into(),
        ];
    let depth_values = vec![volshadow_harness::ndc_depth(&camera, DVec3::new(0.0, 0.0, -2.0)); 256];
    let depth = volshadow_harness::depth_texture(&gpu, size, size, &depth_values);
    let color = volshadow_harness::rgba_texture(&gpu, size, size, &vec![[0.0; 4]; 256]);
    let normal =
        volshadow_harness::rgba_texture(&gpu, size, size, &vec![[0.0, 0.0, 1.0, 0.0]; 256]);
    let albedo =
        volshadow_harness::rgba_texture(&gpu, size, size, &vec![[0.5, 0.5, 0.5, 1.0]; 256]);
    let output = volshadow_harness::texture(
        &gpu,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        (size, size, 1),
        1,
    );
    let settings = Settings {
        output_format: wgpu::TextureFormat::Rgba32Float,
        ..Settings::PREDICTABLE
    };
    let mut vs = VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, settings).unwrap();
    let mut centre = Vec::new();
    let runs = [
        (None, &fog),
        (Some(()), &clear),
        (Some(()), &fog),
        (Some(()), &fog),
    ];
    for (k, (with, medium)) in runs.into_iter().enumerate() {
        let frame = Frame {
            camera: &camera,
            lights: &lights,
            medium,
            occluders: &[],
            scene_color: &color,
            scene_depth: &depth,
            surfaces: with.map(|()| Surfaces {
                normal: &normal,
                albedo: &albedo,
            }),
        };
        let plan = vs.prepare(&gpu.device, &gpu.queue, &frame).unwrap().clone();
        eprintln!("frame {k}:\n{plan}");
        let expected = [
            Some(Reason::NoSurfaceInput),
            Some(Reason::NoScattering),
            None,
            None,
        ][k]
            .clone();
        assert_eq!(
            plan.skip_reason(Pass::IssTable, None),
            expected.as_ref(),
            "frame {k}"
        );
        // Planned in frames 2 and 3; the fourth, its medium unchanged, reuses the table.
        assert_eq!(plan.runs(Pass::IssTable, None), k >= 2, "frame {k}");
        assert_eq!(
            vs.report().reused(Pass::IssTable, None),
            k == 3,
            "frame {k}"
        );
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        vs.encode(&mut encoder, &output).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        centre.push(gpu.read_rgba32f(&output).unwrap()[8 * 16 + 8][0]);
    }
    eprintln!("centre pixel per frame: {centre:?}");
    volshadow_harness::metric::accuracy(
        "the surface term reaching the output: centre pixel with surfaces over without; the reused table's frame against the building one",
        format!(
            "{:.3}×; {}",
            centre[2] / centre[0],
            if centre[2] == centre[3] { "equal" } else { "differ" }
        ),
        "> 1.05× (measured term 0.14 over an airlight of 1.33); equal",
    );
    // With surfaces (frames 2 and 3) the pixel gains the term (measured 0.14 over an airlight
    // of 1.33: the 5% bound is a third of it); frame 3 reuses frame 2's table and matches it.
    assert!(centre[2] > centre[0] * 1.05, "{centre:?}");
    assert_eq!(centre[2], centre[3]);
}

/// Surfaces the composite cannot use are typed errors naming the input, from `prepare`, and
/// leave nothing half-prepared: a normal texture of another size than the frame, an albedo
/// texture without `TEXTURE_BINDING`, an integer-format normal texture.
#[test]
fn bad_surface_textures_are_typed_errors() {
    use volshadow::{Error, Frame, Settings, Surfaces, VolumetricShadows};
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(0.0, 0.0, -2.0),
        50.0,
        1.0,
    );
    let fog = Medium::new(
        Vec3::splat(0.3),
        Vec3::splat(0.05),
        PhaseFunction::Isotropic,
    )
    .unwrap();
    let light = PointLight::new(Vec3::new(0.0, 0.0, -1.5), Vec3::splat(5.0)).unwrap();
    let lights = [Light::from(light).into()];
    let depth = volshadow_harness::depth_texture(&gpu, 16, 16, &[0.5; 256]);
    let color = volshadow_harness::rgba_texture(&gpu, 16, 16, &[[0.0; 4]; 256]);
    let good = volshadow_harness::rgba_texture(&gpu, 16, 16, &[[0.0, 0.0, 1.0, 0.0]; 256]);
    let small = volshadow_harness::rgba_texture(&gpu, 8, 8, &[[0.0, 0.0, 1.0, 0.0]; 64]);
    let no_binding = volshadow_harness::texture(
        &gpu,
        wgpu::TextureFormat::Rgba16Float,
        wgpu::TextureUsages::COPY_DST,
        (16, 16, 1),
        1,
    );
    let integer = volshadow_harness::texture(
        &gpu,
        wgpu::TextureFormat::Rgba8Uint,
        wgpu::TextureUsages::TEXTURE_BINDING,
        (16, 16, 1),
        1,
    );
    let mut vs =
        VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, Settings::PREDICTABLE).unwrap();
    for (normal, albedo, field) in [
        (&small, &good, "surface_normal"),
        (&good, &no_binding, "surface_albedo"),
        (&integer, &good, "surface_normal"),
    ] {
        let frame = Frame {
            camera: &camera,
            lights: &lights,
            medium: &fog,
            occluders: &[],
            scene_color: &color,
            scene_depth: &depth,
            surfaces: Some(Surfaces { normal, albedo }),
        };
        let err = vs.prepare(&gpu.device, &gpu.queue, &frame).err();
        eprintln!("{field}: {err:?}");
        assert!(
            matches!(err, Some(Error::InvalidTexture { field: f, .. }) if f == field),
            "{err:?}"
        );
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let output = volshadow_harness::texture(
            &gpu,
            wgpu::TextureFormat::Rgba16Float,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
            (16, 16, 1),
            1,
        );
        assert!(matches!(
            vs.encode(&mut encoder, &output),
            Err(Error::NotPrepared { .. })
        ));
    }
}

/// The spot-light approximation of the surface term (a point inside the cone gets the point
/// light's whole term, one outside none; what the composite did before `volshadow_iss_spot`)
/// against the term of the
/// cone alone, computed by brute force here: the midpoint rule over the sphere of directions
/// about the direction to the light (γ = π·u² towards its integrable peak, 120 × 240 cells;
/// `tests/cpu/reference_iss.rs` measures this rule within 3.3e-4 of the adaptive reference), with
/// `reference::inscatter` (the cone's own airlight, no occluders) along each direction. Points
/// on a wall 1 below a 60° spot pointing at it (cone edge at 0.577 from the axis), HG 0.3,
/// σt·D ≈ 0.3. A characterisation, not an accuracy bar: measured +130% on the axis, +165% at
/// 0.3, +277% at 0.5 (the point light's glow from the medium outside the cone, which a
/// 60° cone does not light, is counted), and −100% outside the cone (0 where the cone's
/// glow still gives 21% / 12% / 4% of the on-axis term at 0.65 / 0.8 / 1.2). Asserted: it
/// over-counts everywhere inside (at most 3× on the axis) and gives 0 outside where the cone
/// alone gives ≥ 1% of the on-axis term.
#[test]
fn spot_cone_approximation_error() {
    use volshadow::reference::inscatter;
    use volshadow::SpotLight;
    let medium = Medium::new(
        Vec3::splat(0.25),
        Vec3::splat(0.05),
        PhaseFunction::HenyeyGreenstein { g: 0.3 },
    )
    .unwrap();
    let apex = Vec3::new(0.0, 0.0, -1.0);
    let spot = SpotLight::new(apex, Vec3::NEG_Z, 60f32.to_radians(), Vec3::splat(10.0)).unwrap();
    let point = PointLight::new(apex, Vec3::splat(10.0)).unwrap();
    let n = DVec3::Z;
    let cone_term = |p: DVec3| {
        let l = (apex.as_dvec3() - p).normalize();
        let e1 = l.any_orthonormal_vector();
        let e2 = l.cross(e1);
        let (nu, nf) = (120, 240);
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
                    sum += inscatter(p, w, f64::INFINITY, &medium, &spot, &[]).x * c * jac;
                }
            }
        }
        sum
    };
    let edge = (0.5 * 60f64.to_radians()).tan();
    let mut on_axis = 0.0;
    let mut rows = Vec::new();
    for r in [0.0, 0.3, 0.5, 0.65, 0.8, 1.2] {
        let p = DVec3::new(r, 0.0, -2.0);
        let exact = cone_term(p);
        let model = if r <= edge {
            surface_inscatter(p, n, &medium, &point).x
        } else {
            0.0
        };
        if r == 0.0 {
            on_axis = exact;
        }
        eprintln!(
            "r {r:.2} ({}): cone alone {exact:.4e}, approximation {model:.4e}, {:+.1}% ({:.2} of the on-axis term)",
            if r <= edge { "inside" } else { "outside" },
            100.0 * (model - exact) / exact,
            exact / on_axis
        );
        rows.push((r, exact, model));
    }
    let ratio = |r: f64| {
        let &(_, exact, model) = rows.iter().find(|row| row.0 == r).unwrap();
        model / exact
    };
    let &(_, at_08, model_08) = rows.iter().find(|row| row.0 == 0.8).unwrap();
    volshadow_harness::metric::accuracy(
        "a 60° spot's surface term approximated by its point light's inside the cone, none outside, against the cone alone (a characterisation): approximation over exact on the axis, at 0.3, 0.5; at 0.8 (outside)",
        format!(
            "{:.2}×, {:.2}×, {:.2}×; {model_08:.0} where the cone gives {:.0}% of the on-axis term",
            ratio(0.0),
            ratio(0.3),
            ratio(0.5),
            100.0 * at_08 / on_axis
        ),
        "≥ 1× inside, ≤ 3× on the axis; 0 outside where the cone gives ≥ 1%",
    );
    for &(r, exact, model) in &rows {
        if r <= edge {
            assert!(model >= exact, "r {r}: under-counts");
        }
        if r == 0.0 {
            assert!(model <= 3.0 * exact, "on axis: {}", model / exact);
        }
        if r == 0.8 {
            assert!(exact >= 0.01 * on_axis && model == 0.0);
        }
    }
}
