//! The composite's two paths: a target with `STORAGE_BINDING` in a storage format is written by
//! a compute pass, any other by the rasteriser. Both must write the same values, and those must
//! be `Ls·exp(−σt·d) + Σ L_sctr` for the distance `d` the depth buffer encodes (computed here
//! in f64 from the camera's matrices, not by the crate's shaders).

use volshadow_harness::rng;

use glam::Vec3;
use rng::Rng;
use volshadow::nodes::{CompositeInputs, CompositeNode, OutputTarget};
use volshadow::{Cache, Camera, HeadlessGpu, Medium, PhaseFunction};

const W: u32 = 61;
const H: u32 = 37;

struct Inputs {
    camera: Camera,
    medium: Medium,
    color: Vec<[f32; 4]>,
    distance: Vec<f64>,
    inscatter: [Vec<[f32; 4]>; 2],
    textures: Vec<wgpu::Texture>,
}

fn rgba32f(gpu: &HeadlessGpu, values: &[[f32; 4]]) -> wgpu::Texture {
    volshadow_harness::rgba_texture(gpu, W, H, values)
}

/// Seeded colour, in-scatter and distances (a tenth of the pixels sky), an odd size so that
/// the compute pass's last workgroups are partial.
fn inputs(gpu: &HeadlessGpu, seed: u64) -> Inputs {
    let mut rng = Rng::new(seed);
    // Reversed-Z: the f32 depth buffer then holds every distance to about 1e-7 relative, so
    // what is measured is the composite's own arithmetic, not the depth buffer's quantisation.
    let camera = Camera::new(
        glam::camera::rh::view::look_at_mat4(
            Vec3::new(0.3, 1.2, 5.0),
            Vec3::new(-0.2, 0.9, 0.0),
            Vec3::Y,
        ),
        glam::camera::rh::proj::directx::perspective_infinite_reverse(
            70f32.to_radians(),
            W as f32 / H as f32,
            0.05,
        ),
    )
    .unwrap();
    let medium = Medium::new(
        Vec3::new(0.02, 0.03, 0.05),
        Vec3::new(0.01, 0.02, 0.0),
        PhaseFunction::Isotropic,
    )
    .unwrap();
    let n = (W * H) as usize;
    let mut texel = |lo: f64, hi: f64| {
        [
            rng.range(lo, hi) as f32,
            rng.range(lo, hi) as f32,
            rng.range(lo, hi) as f32,
            rng.range(0.0, 1.0) as f32,
        ]
    };
    let color: Vec<[f32; 4]> = (0..n).map(|_| texel(0.0, 4.0)).collect();
    let inscatter = [
        (0..n).map(|_| texel(0.0, 0.5)).collect::<Vec<_>>(),
        (0..n).map(|_| texel(0.0, 0.5)).collect::<Vec<_>>(),
    ];
    let distance: Vec<f64> = (0..n)
        .map(|_| {
            if rng.next() < 0.1 {
                f64::INFINITY
            } else {
                10f64.powf(rng.range(-0.5, 2.0))
            }
        })
        .collect();
    let depths = volshadow_harness::depths_at(&camera, W, H, |_, _| f64::NAN);
    let depths: Vec<f32> = depths
        .iter()
        .enumerate()
        .map(|(i, &far)| {
            let (o, d) = volshadow_harness::pixel_ray(&camera, W, H, i as u32 % W, i as u32 / W);
            if distance[i].is_finite() {
                volshadow_harness::ndc_depth(&camera, o + distance[i] * d)
            } else {
                far
            }
        })
        .collect();
    let textures = vec![
        rgba32f(gpu, &color),
        volshadow_harness::depth_texture(gpu, W, H, &depths),
        rgba32f(gpu, &inscatter[0]),
        rgba32f(gpu, &inscatter[1]),
    ];
    Inputs {
        camera,
        medium,
        color,
        distance,
        inscatter,
        textures,
    }
}

/// A composite node writing `format`, prepared with `inputs` (both in-scatter textures).
fn prepared(
    gpu: &HeadlessGpu,
    cache: &Cache,
    inputs: &Inputs,
    format: wgpu::TextureFormat,
) -> CompositeNode {
    let mut node = CompositeNode::new(&gpu.device, cache, format).unwrap();
    let t = &inputs.textures;
    node.prepare(
        &gpu.device,
        &gpu.queue,
        &CompositeInputs {
            camera: &inputs.camera,
            medium: &inputs.medium,
            scene_color: &t[0],
            scene_depth: &t[1],
            inscatter: &[&t[2], &t[3]],
            surfaces: None,
        },
    )
    .unwrap();
    node
}

/// The composite of `inputs` into a new target of `format` and `usage`; whether it went
/// through the compute pass, and what it wrote.
fn composite(
    gpu: &HeadlessGpu,
    cache: &Cache,
    inputs: &Inputs,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> (bool, Vec<[f32; 4]>) {
    let node = prepared(gpu, cache, inputs, format);
    let target = volshadow_harness::texture(
        gpu,
        format,
        usage | wgpu::TextureUsages::COPY_SRC,
        (W, H, 1),
        1,
    );
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    node.encode(&mut encoder, &OutputTarget::new(&target), None)
        .unwrap();
    gpu.submit_and_wait(encoder).unwrap();
    (node.stores_into(&target), gpu.read_rgba(&target).unwrap())
}

/// The compute pass writes every pixel, to the bit what the fragment pass writes, in the two
/// float formats (an odd-sized image, so partial workgroups too); and what both write is the
/// f64 expectation (alpha passed through) within f32 rounding of exp (relative 1e-5, from
/// WGSL's exp bound of 3 + 2·|x| ULP at |x| ≤ 10, and the reversed-Z depth's 1e-7), plus one
/// f16 ULP in `Rgba16Float`. A compute pass that takes the pixel
/// centre at the integer corner moves every ray by half a pixel and differs from the
/// fragment pass; one that skips the last partial workgroup leaves its pixels at zero.
#[test]
fn compute_and_fragment_composites_write_the_same_values() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let storage = wgpu::TextureUsages::STORAGE_BINDING;
    let render = wgpu::TextureUsages::RENDER_ATTACHMENT;
    for (seed, format) in [
        (1, wgpu::TextureFormat::Rgba32Float),
        (2, wgpu::TextureFormat::Rgba16Float),
    ] {
        let inputs = inputs(&gpu, seed);
        let (stored, compute) = composite(&gpu, &cache, &inputs, format, storage);
        let (stored_both, both) = composite(&gpu, &cache, &inputs, format, storage | render);
        let (rasterised, fragment) = composite(&gpu, &cache, &inputs, format, render);
        assert!(
            stored && stored_both && !rasterised,
            "{format:?}: the path taken"
        );
        let differ = (0..compute.len())
            .filter(|&i| compute[i] != fragment[i] || both[i] != fragment[i])
            .count();
        let half = format == wgpu::TextureFormat::Rgba16Float;
        let mut worst: f64 = 0.0;
        for (i, f) in fragment.iter().enumerate() {
            let d = inputs.distance[i];
            for (c, &written) in f.iter().take(3).enumerate() {
                let sigma = f64::from(inputs.medium.sigma_t()[c]);
                let t = if d.is_finite() {
                    (-sigma * d).exp()
                } else {
                    0.0
                };
                let expected = f64::from(inputs.color[i][c]) * t
                    + f64::from(inputs.inscatter[0][i][c])
                    + f64::from(inputs.inscatter[1][i][c]);
                worst = worst.max((f64::from(written) - expected).abs() / expected.max(1e-3));
            }
            let alpha = f64::from(inputs.color[i][3]);
            worst = worst.max((f64::from(f[3]) - alpha).abs() / alpha.max(1e-3));
        }
        println!("{format:?}: {differ} pixels differ between the passes; worst relative error against f64 {worst:.2e}");
        volshadow_harness::metric::accuracy(
            &format!("{format:?}, {W}×{H}: pixels where the compute and fragment composites differ; the output against the f64 Ls·exp(−σt·d) + ΣL_sctr"),
            format!("{differ}; max {worst:.1e}"),
            if half {
                "0; 9.9e-4 (one f16 ULP, 2^-10, + WGSL's exp bound 1e-5)"
            } else {
                "0; 1e-5 (WGSL's exp bound)"
            },
        );
        assert_eq!(
            differ, 0,
            "{format:?}: the compute and fragment passes differ"
        );
        // Rgba16Float: one f16 ULP (2^-10 relative; a driver may round either way), plus the
        // f32 bound.
        let bound = if half { 2f64.powi(-10) + 1e-5 } else { 1e-5 };
        assert!(
            worst <= bound,
            "{format:?}: relative error {worst:.2e} against f64, over {bound:.0e}"
        );
    }
}

/// A target the compute pass can write needs no `RENDER_ATTACHMENT`; one it cannot (an sRGB
/// format has no storage usage) is refused with a typed error naming it, before recording.
#[test]
fn a_storage_only_target_is_written_and_a_target_with_neither_usage_is_refused() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let inputs = inputs(&gpu, 3);
    let (stored, image) = composite(
        &gpu,
        &cache,
        &inputs,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::STORAGE_BINDING,
    );
    assert!(stored);
    assert!(
        image.iter().all(|p| p.iter().all(|v| v.is_finite())) && image.iter().any(|p| p[0] > 0.0)
    );
    let node = prepared(&gpu, &cache, &inputs, wgpu::TextureFormat::Rgba32Float);
    let target = volshadow_harness::texture(
        &gpu,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::COPY_SRC,
        (W, H, 1),
        1,
    );
    let err = node.check_output(&OutputTarget::new(&target)).unwrap_err();
    println!("{err}");
    assert!(
        matches!(
            err,
            volshadow::Error::InvalidTexture {
                field: "output",
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("STORAGE_BINDING"), "{err}");
}
