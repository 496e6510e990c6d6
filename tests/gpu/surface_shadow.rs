//! `volshadow::SHADOW_WGSL`: surfaces shadowed with the shadow maps volshadow renders. A sphere
//! above the ground under a point light (cube map), a spot light (one face) and a directional
//! light (orthographic): the helper's
//! visibility of ground points and of points on the sphere itself against exact geometry; and
//! under a point and a spot light with a radius, its soft visibility against the f64
//! reference's exact visible fraction of the light's disc.

use volshadow::nodes::{Encode, Node};

use glam::{DVec3, Vec3};
use volshadow::nodes::{ShadowMapInputs, ShadowMapNode, ShadowMapSettings};
use volshadow::scene::shapes::uv_sphere;
use volshadow::scene::Camera;
use volshadow::{
    DirectionalLight, HeadlessGpu, Light, Occluder, OccluderMesh, PointLight, SpotLight,
};

const CENTRE: Vec3 = Vec3::new(0.0, 1.5, 0.0);
const RADIUS: f32 = 0.5;

/// Evaluates `volshadow_shadow` at `points` (point, normal) in a compute pass; `hard`: with the
/// radius in the params set to 0 (the hard lookup in the same map).
fn visibility(
    gpu: &HeadlessGpu,
    light: &Light,
    points: &[(Vec3, Vec3)],
    normal_offset: Option<f32>,
    hard: bool,
) -> Vec<f32> {
    let device = &gpu.device;
    let cache = volshadow_harness::cache(gpu);
    let mesh = OccluderMesh::new(device, &uv_sphere(CENTRE, RADIUS, 64, 32).unwrap());
    let occluders = [Occluder {
        mesh: &mesh,
        transform: glam::Mat4::IDENTITY,
    }];
    let mut node = ShadowMapNode::new(device, &cache, ShadowMapSettings::default()).unwrap();
    // A camera above the ground looking down at it, so a directional light's fitted map
    // covers every point (point and spot lights do not read it).
    let camera = Camera::new(
        glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 6.0, 0.0), Vec3::ZERO, Vec3::Z),
        glam::camera::rh::proj::directx::perspective(1.2, 1.0, 0.1, 100.0),
    )
    .unwrap();
    let inputs = ShadowMapInputs {
        light,
        occluders: &occluders,
        camera: &camera,
        fallback: None,
    };
    node.prepare(device, &gpu.queue, &inputs).unwrap();
    let mut encoder = device.create_command_encoder(&Default::default());
    node.encode(&mut encoder, None).unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    let map = node.shadow_map().unwrap();
    let mut params = map.params(light, normal_offset);
    if hard {
        params.radius = 0.0;
    }

    use wgpu::util::DeviceExt;
    let storage = |contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents,
            usage: wgpu::BufferUsages::STORAGE | usage,
        })
    };
    let params = storage(bytemuck::bytes_of(&params), wgpu::BufferUsages::empty());
    let data: Vec<[f32; 8]> = points
        .iter()
        .map(|(p, n)| [p.x, p.y, p.z, 0.0, n.x, n.y, n.z, 0.0])
        .collect();
    let input = storage(bytemuck::cast_slice(&data), wgpu::BufferUsages::empty());
    let output = storage(&vec![0u8; 4 * points.len()], wgpu::BufferUsages::COPY_SRC);
    let source = format!(
        "{}\n{}",
        volshadow::SHADOW_WGSL,
        r#"
@group(0) @binding(0) var map: texture_depth_2d_array;
@group(0) @binding(1) var cmp: sampler_comparison;
@group(0) @binding(2) var<storage, read> sm: VolshadowShadow;
@group(0) @binding(3) var<storage, read> points: array<array<vec4<f32>, 2>>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= arrayLength(&out)) { return; }
    let q = points[id.x];
    out[id.x] = volshadow_shadow(map, cmp, sm, q[0].xyz, q[1].xyz);
}"#
    );
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: None,
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: None,
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        compare: Some(wgpu::CompareFunction::GreaterEqual),
        ..Default::default()
    });
    let view = map.texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&view),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::Sampler(&sampler),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: params.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: input.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 4,
                resource: output.as_entire_binding(),
            },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups((points.len() as u32).div_ceil(64), 1, 1);
    }
    gpu.submit_and_wait(encoder).unwrap();
    bytemuck::cast_slice(&gpu.read_buffer_bytes(&output).unwrap()).to_vec()
}

/// Closest approach of the segment from `p` to `light` to the sphere's centre, over the radius.
fn clearance(p: DVec3, light: DVec3) -> f64 {
    let c = CENTRE.as_dvec3();
    let d = light - p;
    let t = ((c - p).dot(d) / d.length_squared()).clamp(0.0, 1.0);
    (p + d * t - c).length() / f64::from(RADIUS)
}

/// Ground points on a 48² grid and points on the sphere (normal outward), each classified by
/// exact geometry: a ground point whose segment to the light passes 3% inside the sphere must
/// read shadowed (< 0.01), 3% outside lit (> 0.99); a sphere point facing the light
/// (n·l > 0.45, up to 63° from it) lit, one facing away (n·l < −0.2) shadowed. Zero
/// misclassified points for a point, a spot and a directional light; with the normal offset switched off the
/// sphere's lit side reads shadowed in places (self-shadowing acne), so the count is not zero.
#[test]
fn helper_matches_exact_geometry() {
    let gpu = volshadow_harness::gpu();
    let lights: [(&str, Light); 3] = [
        (
            "point",
            PointLight::new(Vec3::new(0.3, 3.2, 0.2), Vec3::ONE)
                .unwrap()
                .into(),
        ),
        (
            "spot",
            SpotLight::new(Vec3::new(-0.3, 3.4, 0.1), Vec3::NEG_Y, 1.6, Vec3::ONE)
                .unwrap()
                .into(),
        ),
        (
            "directional",
            DirectionalLight::new(Vec3::new(0.15, -1.0, 0.1).normalize(), Vec3::ONE)
                .unwrap()
                .with_shadow_distance(10.0)
                .unwrap()
                .into(),
        ),
    ];
    let mut points = Vec::new();
    for i in 0..48 {
        for j in 0..48 {
            let p = Vec3::new(
                -2.0 + 4.0 * i as f32 / 47.0,
                0.0,
                -2.0 + 4.0 * j as f32 / 47.0,
            );
            points.push((p, Vec3::Y));
        }
    }
    for i in 0..40 {
        for j in 0..20 {
            let phi = i as f32 / 40.0 * std::f32::consts::TAU;
            let theta = (j as f32 + 0.5) / 20.0 * std::f32::consts::PI;
            let n = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            points.push((CENTRE + n * RADIUS, n));
        }
    }
    let mut acne = 0;
    for (name, light) in lights {
        // The point towards the light: a directional light's is 1e4 away against its direction.
        let toward = |p: DVec3| match &light {
            Light::Directional(d) => p - 1e4 * d.direction().as_dvec3(),
            _ => light.position().unwrap().as_dvec3(),
        };
        let misclassified = |vis: &[f32]| {
            let mut bad = 0;
            let mut checked = 0;
            for (&(p, n), &v) in points.iter().zip(vis) {
                let (p, n) = (p.as_dvec3(), n.as_dvec3());
                let expected = if n == DVec3::Y {
                    let c = clearance(p, toward(p));
                    (!(0.97..=1.03).contains(&c)).then_some(c > 1.0)
                } else {
                    let nl = n.dot((toward(p) - p).normalize());
                    (!(-0.2..=0.45).contains(&nl)).then_some(nl > 0.0)
                };
                if let Some(lit) = expected {
                    checked += 1;
                    bad += usize::from(if lit { v <= 0.99 } else { v >= 0.01 });
                }
            }
            (bad, checked)
        };
        let (bad, checked) = misclassified(&visibility(&gpu, &light, &points, None, false));
        let (no_offset, _) = misclassified(&visibility(&gpu, &light, &points, Some(0.0), false));
        eprintln!(
            "{name}: {bad} of {checked} misclassified; without the normal offset {no_offset}"
        );
        volshadow_harness::metric::accuracy(
            &format!("{name}: SHADOW_WGSL surface visibility against exact geometry, 1024² map; without the normal offset"),
            format!("{bad} of {checked} misclassified; {no_offset}"),
            "0; acne without the offset in one light at least",
        );
        assert_eq!(bad, 0, "{name}");
        acne += no_offset;
    }
    assert!(
        acne > 0,
        "the normal offset changes nothing: the acne check is not discriminative"
    );
}

/// The soft test's bars per light (point, spot): ground mean, ground p95, sphere mean, sphere
/// p95 of |visibility − reference| (see `soft_matches_reference`).
const BARS: [[f64; 4]; 2] = [[0.055, 0.15, 0.004, 0.01], [0.07, 0.19, 0.004, 0.01]];

/// The `q`-quantile of `v` (nearest rank).
fn quantile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    let i = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1;
    v[i]
}

/// Mean and p95 of `|a − b|`.
fn mean_p95(errors: &mut [f64]) -> (f64, f64) {
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    (mean, quantile(errors, 0.95))
}

/// Soft surface shadows: a light of radius 0.4 whose centre is 1.52 from the sphere's (radius
/// 0.5), a point light (cube map) and a spot light (one face), against
/// `reference::soft::visible_fraction`, exact for one sphere. Ground points on 24 radial lines
/// from the shadow's centre, from inside the umbra to beyond the penumbra (three points past
/// each end of the penumbra); sphere points on a 40 × 20 grid (lit side, terminator,
/// shadowed side), the reference taken just outside the sphere (there the sphere hides what
/// lies below the tangent plane).
///
/// Measured on lavapipe (bars in `BARS`: the ground's the measured figure plus about 20%, the
/// sphere's about twice it, its p95 held to 1%; the taps' turn is an integer hash, the same on
/// every GPU, but another rasteriser draws the map's outline a little differently):
/// - point: ground mean 4.48%, p95 12.50%; sphere mean 0.18%, p95 0.46%;
/// - spot: ground mean 5.93%, p95 16.21%; sphere mean 0.15%, p95 0.45%.
///
/// The hard lookup in the same maps (radius 0 in the params) misses the ground's bars by far:
/// mean 18.75% (spot 18.63%), p95 46.45% (45.93%); on the sphere mean 3.85%, p95 32.55% (its
/// terminator, where the light sets behind the surface's own horizon). What is left on the
/// ground is the deep penumbra and the umbra's edge, too bright by up to 0.2: the front layer
/// alone puts the blocker nearer the light than the sphere's outline, so the filter is too
/// wide (see `docs/METHOD.md`).
#[test]
fn soft_matches_reference() {
    let gpu = volshadow_harness::gpu();
    const R: f32 = 0.4;
    let position = Vec3::new(0.2, 3.0, 0.1);
    let lights: [(&str, Light); 2] = [
        (
            "point",
            PointLight::new(position, Vec3::ONE)
                .unwrap()
                .with_radius(R)
                .unwrap()
                .into(),
        ),
        (
            "spot",
            SpotLight::new(position, Vec3::NEG_Y, 1.6, Vec3::ONE)
                .unwrap()
                .with_radius(R)
                .unwrap()
                .into(),
        ),
    ];
    let occluders: Vec<volshadow::reference::Occluder> =
        vec![volshadow::reference::Sphere::new(CENTRE.as_dvec3(), f64::from(RADIUS)).into()];
    let light_c = position.as_dvec3();
    let fraction = |x: DVec3| {
        volshadow::reference::soft::visible_fraction(x, light_c, f64::from(R), &occluders)
    };
    // The ground: radial lines from where the sphere's centre projects from the light.
    let l = light_c;
    let c = CENTRE.as_dvec3();
    let t = l.y / (l.y - c.y);
    let centre = l + (c - l) * t;
    let mut ground = Vec::new();
    for i in 0..24 {
        let phi = i as f64 / 24.0 * std::f64::consts::TAU;
        let line: Vec<(DVec3, f64)> = (0..=200)
            .map(|k| {
                let r = 2.5 * k as f64 / 200.0;
                let x = centre + DVec3::new(r * phi.cos(), 0.0, r * phi.sin());
                (x, fraction(x))
            })
            .collect();
        let first = line.iter().position(|&(_, f)| f > 0.0).unwrap();
        let last = line.iter().rposition(|&(_, f)| f < 1.0).unwrap();
        ground.extend(&line[first.saturating_sub(3)..(last + 4).min(line.len())]);
    }
    let mut sphere = Vec::new();
    for i in 0..40 {
        for j in 0..20 {
            let phi = i as f64 / 40.0 * std::f64::consts::TAU;
            let theta = (j as f64 + 0.5) / 20.0 * std::f64::consts::PI;
            let n = DVec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            let x = c + n * f64::from(RADIUS) * (1.0 + 1e-9);
            sphere.push((x, n, fraction(x)));
        }
    }
    let penumbra = ground.iter().filter(|(_, f)| *f > 0.0 && *f < 1.0).count();
    eprintln!(
        "{} ground points ({penumbra} in the penumbra), {} sphere points",
        ground.len(),
        sphere.len()
    );
    let points: Vec<(Vec3, Vec3)> = ground
        .iter()
        .map(|&(x, _)| (x.as_vec3(), Vec3::Y))
        .chain(sphere.iter().map(|&(x, n, _)| (x.as_vec3(), n.as_vec3())))
        .collect();
    let refs: Vec<f64> = ground
        .iter()
        .map(|g| g.1)
        .chain(sphere.iter().map(|s| s.2))
        .collect();
    // Mean and p95 of |visibility − reference| on the ground and on the sphere.
    let measure = |vis: &[f32]| {
        assert!(vis.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)));
        let mut g: Vec<f64> = (0..ground.len())
            .map(|i| (f64::from(vis[i]) - refs[i]).abs())
            .collect();
        let mut s: Vec<f64> = (ground.len()..points.len())
            .map(|i| (f64::from(vis[i]) - refs[i]).abs())
            .collect();
        let (g, s) = (mean_p95(&mut g), mean_p95(&mut s));
        [g.0, g.1, s.0, s.1]
    };
    let pct = |e: [f64; 4]| {
        format!(
            "ground mean {:.2}% p95 {:.2}%; sphere mean {:.2}% p95 {:.2}%",
            100.0 * e[0],
            100.0 * e[1],
            100.0 * e[2],
            100.0 * e[3]
        )
    };
    for ((name, light), bars) in lights.iter().zip(BARS) {
        let soft = measure(&visibility(&gpu, light, &points, None, false));
        let hard = measure(&visibility(&gpu, light, &points, None, true));
        eprintln!("{name}: soft {}; hard {}", pct(soft), pct(hard));
        volshadow_harness::metric::accuracy(
            &format!("{name} light of radius 0.4, sphere 0.5 at 1.52: SHADOW_WGSL soft surface visibility against the exact visible fraction ({} ground points umbra to lit, {} on the sphere), 1024² map; the hard lookup (radius 0 in the params)", ground.len(), sphere.len()),
            format!("{}; hard {}", pct(soft), pct(hard)),
            format!("{} (ground: measured + about 20%; sphere: about twice the measured, p95 held to 1%); the hard lookup above the ground's bars", pct(bars)),
        );
        for (k, what) in ["ground mean", "ground p95", "sphere mean", "sphere p95"]
            .iter()
            .enumerate()
        {
            assert!(
                soft[k] <= bars[k],
                "{name}: soft {what} {} > {}",
                soft[k],
                bars[k]
            );
        }
        assert!(
            hard[0] > bars[0] && hard[1] > bars[1],
            "{name}: the hard lookup passes the ground's soft bars: not discriminative"
        );
    }
    // Radius 0 is the hard lookup: in the point light's map (the same cube faces with and
    // without a radius), the radius zeroed in the params reads what a point light's params do.
    let zeroed = visibility(&gpu, &lights[0].1, &points, None, true);
    let point: Light = PointLight::new(position, Vec3::ONE).unwrap().into();
    let plain = visibility(&gpu, &point, &points, None, false);
    let differing = zeroed
        .iter()
        .zip(&plain)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert_eq!(
        differing, 0,
        "radius 0 differs from the point light's hard lookup"
    );
}
