//! GPU time and error of the hybrid march against brute force, and of reduced-resolution
//! scattering, on the sphere scene (issues 3 and 4). Sequential, median of 5 warm frames of
//! timestamp queries, errors against the f64 reference.
//!
//! ```text
//! cargo bench --bench hybrid_vs_brute
//! ```

#[path = "../tests/common/mod.rs"]
mod common;

use glam::{DVec3, Mat4, Vec3};
use volshadow::nodes::{MarchMethod, MarchSettings, Scale, UpsampleFilter};
use volshadow::reference::{self, TriangleMesh};
use volshadow::scene::shapes;
use volshadow::{
    Cache, Frame, Light, Medium, Occluder, OccluderMesh, PhaseFunction, PointLight, Settings,
    VolumetricShadows,
};

const SIZE: u32 = 256;

fn main() {
    let gpu = common::gpu_timed();
    let adapter = gpu.adapter_summary();
    let cache = Cache::new(&gpu.device);
    let camera = common::look_at(
        Vec3::new(0.0, 1.2, 5.0),
        Vec3::new(0.0, 0.9, 0.0),
        60.0,
        1.0,
    );
    let light: Light = PointLight::new(Vec3::new(0.4, 4.2, -0.3), Vec3::new(30.0, 28.0, 25.0))
        .unwrap()
        .into();
    let medium = Medium::new(
        Vec3::new(0.25, 0.27, 0.30),
        Vec3::splat(0.03),
        PhaseFunction::HenyeyGreenstein { g: 0.3 },
    )
    .unwrap();
    let center = Vec3::new(0.0, 2.0, 0.0);
    let mesh = shapes::uv_sphere(center, 0.6, 24, 12);
    let distance = |o: DVec3, d: DVec3| -> f64 {
        let mut t = if d.y < 0.0 { -o.y / d.y } else { f64::INFINITY };
        let oc = o - center.as_dvec3();
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - 0.36);
        if disc >= 0.0 && -b - disc.sqrt() > 0.0 {
            t = t.min(-b - disc.sqrt());
        }
        t
    };
    let depths: Vec<f32> = (0..SIZE * SIZE)
        .map(|i| {
            let (o, d) = common::pixel_ray(&camera, SIZE, SIZE, i % SIZE, i / SIZE);
            let ds = distance(o, d);
            if ds.is_finite() {
                common::ndc_depth(&camera, o + ds * d)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = common::depth_texture(&gpu, SIZE, SIZE, &depths);
    let color = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: depth.size(),
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba16Float,
        usage: wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    let output = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: depth.size(),
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba32Float,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let gpu_mesh = OccluderMesh::new(&gpu.device, &mesh);
    let occluders = [Occluder {
        mesh: &gpu_mesh,
        transform: Mat4::IDENTITY,
    }];
    eprintln!("reference at {SIZE}x{SIZE} …");
    let ref_occ = [reference::Occluder::Mesh(TriangleMesh::from_indexed(
        mesh.positions(),
        mesh.indices(),
        glam::DMat4::IDENTITY,
    ))];
    let reference =
        reference::inscatter_image(&camera, SIZE, SIZE, distance, &medium, &light, &ref_occ);
    let pixel_angle = 2.0 * f64::from(camera.pixel_angular_radius(SIZE));
    let keep: Vec<bool> = (0..reference.len())
        .map(|i| {
            let (o, d) = common::pixel_ray(&camera, SIZE, SIZE, i as u32 % SIZE, i as u32 / SIZE);
            d.angle_between(light.position().as_dvec3() - o) >= 1.5 * pixel_angle
        })
        .collect();

    let configs: Vec<(String, MarchSettings, UpsampleFilter, bool)> = {
        let m = |method, steps, scale| MarchSettings {
            method,
            steps,
            scale,
            ..MarchSettings::default()
        };
        let mut v = vec![(
            "analytic (no occluders)".to_string(),
            m(MarchMethod::Hybrid, 1, Scale::Full),
            UpsampleFilter::DepthAware3x3,
            false,
        )];
        for steps in [16, 32, 64, 128, 256] {
            v.push((
                format!("brute force {steps}"),
                m(MarchMethod::BruteForce, steps, Scale::Full),
                UpsampleFilter::DepthAware3x3,
                true,
            ));
            v.push((
                format!("hybrid {steps}"),
                m(MarchMethod::Hybrid, steps, Scale::Full),
                UpsampleFilter::DepthAware3x3,
                true,
            ));
        }
        v.push((
            "hybrid 64 @1/2 3x3".into(),
            m(MarchMethod::Hybrid, 64, Scale::Half),
            UpsampleFilter::DepthAware3x3,
            true,
        ));
        v.push((
            "hybrid 64 @1/4 3x3".into(),
            m(MarchMethod::Hybrid, 64, Scale::Quarter),
            UpsampleFilter::DepthAware3x3,
            true,
        ));
        v
    };
    println!("# hybrid vs brute force, sphere scene {SIZE}x{SIZE}, {adapter}");
    println!("| configuration | march ms (median of 5) | all passes ms | in-scatter RMSE / mean |");
    println!("|---|---|---|---|");
    for (name, march, upsample, shadows) in configs {
        let settings = Settings {
            march,
            upsample,
            output_format: wgpu::TextureFormat::Rgba32Float,
            ..Settings::PREDICTABLE
        };
        let mut vs = VolumetricShadows::new(&gpu.device, &gpu.queue, &cache, settings).unwrap();
        let lights = [light.into()];
        let frame = Frame {
            camera: &camera,
            lights: &lights,
            medium: &medium,
            occluders: if shadows { &occluders } else { &[] },
            scene_color: &color,
            scene_depth: &depth,
        };
        let mut march_ms = Vec::new();
        let mut total_ms = Vec::new();
        for i in 0..7 {
            vs.prepare(&gpu.device, &gpu.queue, &frame).unwrap();
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            vs.encode(&mut encoder, &output.create_view(&Default::default()))
                .unwrap();
            gpu.submit_and_wait(encoder).unwrap();
            let t = vs.read_timings(&gpu.device).unwrap();
            if i >= 2 {
                march_ms.push(
                    t.iter()
                        .filter(|p| p.label == "march")
                        .map(|p| p.ms)
                        .sum::<f64>(),
                );
                total_ms.push(t.iter().map(|p| p.ms).sum::<f64>());
            }
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let texels = gpu.read_rgba32f(vs.inscatter(0).unwrap()).unwrap();
        let (mut sq, mut sum, mut n) = (0.0, 0.0, 0.0);
        for (i, r) in reference.iter().enumerate().filter(|(i, _)| keep[*i]) {
            for c in 0..3 {
                sq += (f64::from(texels[i][c]) - r[c]).powi(2);
                sum += r[c];
                n += 1.0;
            }
        }
        println!(
            "| {name} | {:.2} | {:.2} | {:.4} |",
            median(&mut march_ms),
            median(&mut total_ms),
            (sq / n).sqrt() / (sum / n)
        );
    }
}
