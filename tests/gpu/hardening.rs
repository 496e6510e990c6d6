//! Bad use of the facade is a typed error, never a panic, a wgpu validation error behind `Ok`,
//! or a silently wrong image: encoding without a prepared frame, output subresources of the
//! wrong size, output formats the composite cannot write, layered light textures, and occluder
//! sets beyond the device's buffer limits.

use glam::{Mat4, Vec3};
use volshadow::nodes::{OutputTarget, TableSize};
use volshadow::scene::shapes;
use volshadow::{
    Cache, Camera, Error, Frame, FrameLight, HeadlessGpu, Light, Medium, Occluder, OccluderMesh,
    PhaseFunction, PointLight, Settings, SpotLight, VolumetricShadows,
};

struct Rig {
    gpu: HeadlessGpu,
    cache: Cache,
    camera: Camera,
    color: wgpu::Texture,
    depth: wgpu::Texture,
    size: u32,
}

use volshadow_harness::texture;

fn output(gpu: &HeadlessGpu, size: u32, mips: u32) -> wgpu::Texture {
    texture(
        gpu,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        (size, size, 1),
        mips,
    )
}

/// A ground plane at y = 0 seen from above, scene colour 0.5, `size`².
fn rig_on(gpu: HeadlessGpu, size: u32) -> Rig {
    let cache = volshadow_harness::cache(&gpu);
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 1.5, 5.0),
        Vec3::new(0.0, 1.0, 0.0),
        60.0,
        1.0,
    );
    let depths: Vec<f32> = (0..size * size)
        .map(|i| {
            let (o, d) = volshadow_harness::pixel_ray(&camera, size, size, i % size, i / size);
            if d.y < 0.0 {
                volshadow_harness::ndc_depth(&camera, o + (-o.y / d.y) * d)
            } else {
                camera.far_depth()
            }
        })
        .collect();
    let depth = volshadow_harness::depth_texture(&gpu, size, size, &depths);
    let color = texture(
        &gpu,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        (size, size, 1),
        1,
    );
    let texels = vec![[0.5f32, 0.5, 0.5, 1.0]; (size * size) as usize];
    gpu.queue.write_texture(
        color.as_image_copy(),
        bytemuck::cast_slice(&texels),
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(size * 16),
            rows_per_image: Some(size),
        },
        color.size(),
    );
    Rig {
        gpu,
        cache,
        camera,
        color,
        depth,
        size,
    }
}

fn rig(size: u32) -> Rig {
    rig_on(volshadow_harness::gpu(), size)
}

fn settings() -> Settings {
    Settings {
        output_format: wgpu::TextureFormat::Rgba32Float,
        ..Settings::PREDICTABLE
    }
}

fn medium() -> Medium {
    Medium::new(
        Vec3::splat(0.15),
        Vec3::splat(0.03),
        PhaseFunction::HenyeyGreenstein { g: 0.4 },
    )
    .unwrap()
}

fn point(position: Vec3) -> FrameLight<'static> {
    Light::from(PointLight::new(position, Vec3::splat(30.0)).unwrap()).into()
}

fn frame<'a>(
    rig: &'a Rig,
    lights: &'a [FrameLight<'a>],
    medium: &'a Medium,
    occluders: &'a [Occluder<'a>],
) -> Frame<'a> {
    Frame {
        camera: &rig.camera,
        lights,
        medium,
        occluders,
        scene_color: &rig.color,
        scene_depth: &rig.depth,
        surfaces: None,
    }
}

/// Prepares, encodes into `target`, submits; panics on any error.
fn render(rig: &Rig, vs: &mut VolumetricShadows, frame: &Frame, target: OutputTarget) {
    vs.prepare(&rig.gpu.device, &rig.gpu.queue, frame).unwrap();
    let mut encoder = rig.gpu.device.create_command_encoder(&Default::default());
    vs.encode(&mut encoder, target).unwrap();
    rig.gpu.submit_and_wait(encoder).unwrap();
}

/// Reads mip `level` of an `Rgba32Float` texture (copied into a single-mip texture first).
fn read_mip(gpu: &HeadlessGpu, source: &wgpu::Texture, level: u32) -> Vec<[f32; 4]> {
    let w = (source.width() >> level).max(1);
    let h = (source.height() >> level).max(1);
    let copy = texture(
        gpu,
        source.format(),
        wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::COPY_SRC,
        (w, h, 1),
        1,
    );
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_texture(
        wgpu::TexelCopyTextureInfo {
            texture: source,
            mip_level: level,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        copy.as_image_copy(),
        copy.size(),
    );
    gpu.submit_and_wait(encoder).unwrap();
    gpu.read_rgba32f(&copy).unwrap()
}

fn max_abs_diff(a: &[[f32; 4]], b: &[[f32; 4]]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..4).map(move |c| (x[c] - y[c]).abs()))
        .fold(0.0, f32::max)
}

fn not_prepared(result: volshadow::Result<()>) -> bool {
    matches!(result, Err(Error::NotPrepared { .. }))
}

/// Runs `f` inside a validation error scope; returns its result and the captured error.
fn scoped<T>(device: &wgpu::Device, f: impl FnOnce() -> T) -> (T, Option<wgpu::Error>) {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = f();
    let error = pollster::block_on(scope.pop());
    (value, error)
}

#[test]
fn encode_needs_a_successful_prepare_of_the_current_frame() {
    let rig = rig(32);
    let out = output(&rig.gpu, rig.size, 1);
    let device = &rig.gpu.device;
    let medium = medium();
    let sphere = OccluderMesh::new(
        device,
        &shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.5, 16, 8).unwrap(),
    );
    let occluders = [Occluder {
        mesh: &sphere,
        transform: Mat4::IDENTITY,
    }];
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    let f = frame(&rig, &lights, &medium, &occluders);
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    let mut encoder = device.create_command_encoder(&Default::default());

    // Before any prepare: nothing to record (was `Ok`, recording nothing).
    let r = vs.encode(&mut encoder, &out);
    assert!(not_prepared(r.clone()), "before prepare: {r:?}");

    // After invalidate (was a panic: index out of bounds).
    render(&rig, &mut vs, &f, (&out).into());
    vs.invalidate();
    let r = vs.encode(&mut encoder, &out);
    assert!(not_prepared(r.clone()), "after invalidate: {r:?}");
    let r = vs.encode_step(&mut encoder, &out, 0);
    assert!(
        not_prepared(r.clone()),
        "encode_step after invalidate: {r:?}"
    );

    // After set_settings with a new table or shadow-map size (was the same panic).
    render(&rig, &mut vs, &f, (&out).into());
    vs.set_settings(Settings {
        table: TableSize {
            along_ray: 128,
            across_rays: 128,
        },
        ..settings()
    })
    .unwrap();
    let r = vs.encode(&mut encoder, &out);
    assert!(not_prepared(r.clone()), "after set_settings: {r:?}");
    render(&rig, &mut vs, &f, (&out).into());
    vs.set_settings(Settings {
        shadow_map: volshadow::nodes::ShadowMapSettings {
            resolution: 512,
            ..Default::default()
        },
        ..settings()
    })
    .unwrap();
    let r = vs.encode(&mut encoder, &out);
    assert!(
        not_prepared(r.clone()),
        "after a new shadow-map size: {r:?}"
    );
    drop(encoder);
}

#[test]
fn a_failed_prepare_leaves_no_mixed_frame() {
    let rig = rig(32);
    let out = output(&rig.gpu, rig.size, 1);
    let device = &rig.gpu.device;
    let medium = medium();
    let sphere = OccluderMesh::new(
        device,
        &shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.5, 16, 8).unwrap(),
    );
    let occluders = [Occluder {
        mesh: &sphere,
        transform: Mat4::IDENTITY,
    }];
    // A texture no spot can use (integer texels cannot be filtered): fails light 1's prepare
    // after light 0's uploads.
    let bad_texture = texture(
        &rig.gpu,
        wgpu::TextureFormat::Rgba8Uint,
        wgpu::TextureUsages::TEXTURE_BINDING,
        (8, 8, 1),
        1,
    );
    let spot = Light::from(
        SpotLight::new(
            Vec3::new(-1.0, 4.0, 0.0),
            Vec3::NEG_Y,
            1.0,
            Vec3::splat(20.0),
        )
        .unwrap(),
    );
    let (a, b) = (Vec3::new(0.4, 4.5, -0.5), Vec3::new(-0.6, 3.8, 0.3));
    let first = [point(a), spot.into()];
    let failing = [
        point(b),
        FrameLight {
            light: spot,
            texture: Some(&bad_texture),
            casters: None,
            texture_channels: Default::default(),
        },
    ];
    let second = [point(b), spot.into()];

    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    render(
        &rig,
        &mut vs,
        &frame(&rig, &first, &medium, &occluders),
        (&out).into(),
    );
    let err = vs
        .prepare(
            device,
            &rig.gpu.queue,
            &frame(&rig, &failing, &medium, &occluders),
        )
        .err();
    assert!(
        matches!(
            err,
            Some(Error::InvalidTexture {
                field: "light_texture",
                ..
            })
        ),
        "{err:?}"
    );
    // Was `Ok`, recording light 0 of the failed frame with light 1 of the first.
    let mut encoder = device.create_command_encoder(&Default::default());
    let r = vs.encode(&mut encoder, &out);
    assert!(not_prepared(r.clone()), "after a failed prepare: {r:?}");
    drop(encoder);

    // The next valid frame is exactly what a fresh facade renders: nothing of the failed
    // prepare's uploads is taken for already rendered (the shadow map and F' table of light 0
    // moved to `b` during the failed prepare and must still be rebuilt).
    render(
        &rig,
        &mut vs,
        &frame(&rig, &second, &medium, &occluders),
        (&out).into(),
    );
    let got = rig.gpu.read_rgba32f(&out).unwrap();
    let mut fresh = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    let out2 = output(&rig.gpu, rig.size, 1);
    render(
        &rig,
        &mut fresh,
        &frame(&rig, &second, &medium, &occluders),
        (&out2).into(),
    );
    let want = rig.gpu.read_rgba32f(&out2).unwrap();
    let diff = max_abs_diff(&got, &want);
    println!("after a failed prepare: max |difference| from a fresh facade {diff:.3e}");
    // Same device, same inputs, same passes: the images are bit-identical.
    assert_eq!(diff, 0.0);
}

#[test]
fn output_size_is_checked_at_the_written_mip_level() {
    // Frame 24²: mip 1 of a 48² texture fits (was rejected: the texture is 48²) and gets
    // exactly the image a plain 24² target gets.
    let small = rig(24);
    let device = &small.gpu.device;
    let medium = medium();
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    let f = frame(&small, &lights, &medium, &[]);
    let mut vs =
        VolumetricShadows::new(device, &small.gpu.queue, &small.cache, settings()).unwrap();
    let plain = output(&small.gpu, 24, 1);
    render(&small, &mut vs, &f, (&plain).into());
    let want = small.gpu.read_rgba32f(&plain).unwrap();
    let mipped = output(&small.gpu, 48, 2);
    let mip1 = OutputTarget {
        texture: &mipped,
        mip_level: 1,
        array_layer: 0,
    };
    render(&small, &mut vs, &f, mip1);
    let got = read_mip(&small.gpu, &mipped, 1);
    assert_eq!(max_abs_diff(&got, &want), 0.0);
    let mean: f32 = got.iter().map(|t| t[0]).sum::<f32>() / got.len() as f32;
    assert!(mean > 0.0, "mip 1 was not written");

    // Mip 0 of the same texture (48²), a missing mip level or array layer: typed errors.
    let mut encoder = device.create_command_encoder(&Default::default());
    for (target, what) in [
        (OutputTarget::new(&mipped), "48x48"),
        (
            OutputTarget {
                mip_level: 2,
                ..mip1
            },
            "mip level 2",
        ),
        (
            OutputTarget {
                array_layer: 1,
                ..mip1
            },
            "array layer 1",
        ),
    ] {
        let r = vs.encode(&mut encoder, target);
        match r {
            Err(Error::InvalidTexture {
                field: "output",
                problem,
            }) => assert!(problem.contains(what), "{problem}"),
            other => panic!("{what}: {other:?}"),
        }
    }
    drop(encoder);

    // Frame 48²: mip 1 (24²) is rejected (was accepted, writing the top-left 24² crop).
    let large = rig_on(small.gpu, 48);
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    let f = frame(&large, &lights, &medium, &[]);
    let mut vs = VolumetricShadows::new(
        &large.gpu.device,
        &large.gpu.queue,
        &large.cache,
        settings(),
    )
    .unwrap();
    vs.prepare(&large.gpu.device, &large.gpu.queue, &f).unwrap();
    let mut encoder = large.gpu.device.create_command_encoder(&Default::default());
    let r = vs.encode(
        &mut encoder,
        OutputTarget {
            texture: &mipped,
            mip_level: 1,
            array_layer: 0,
        },
    );
    assert!(
        matches!(
            r,
            Err(Error::InvalidTexture {
                field: "output",
                ..
            })
        ),
        "{r:?}"
    );
}

#[test]
fn output_formats_the_composite_cannot_write_are_rejected_by_new() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    use wgpu::TextureFormat as F;
    for format in [
        F::Rgba8Uint,
        F::R32Sint,
        F::Rg16Uint,
        F::Depth32Float,
        F::Bc1RgbaUnorm,
    ] {
        let (result, error) = scoped(&gpu.device, || {
            VolumetricShadows::new(
                &gpu.device,
                &gpu.queue,
                &cache,
                Settings {
                    output_format: format,
                    ..Settings::default()
                },
            )
            .err()
        });
        assert!(
            matches!(
                result,
                Some(Error::InvalidTexture {
                    field: "output_format",
                    ..
                })
            ),
            "{format:?}: {result:?}"
        );
        assert!(error.is_none(), "{format:?}: {error:?}");
    }
    for format in [
        F::Rgba16Float,
        F::Rgba8UnormSrgb,
        F::Bgra8Unorm,
        F::Rgba32Float,
    ] {
        let (result, error) = scoped(&gpu.device, || {
            VolumetricShadows::new(
                &gpu.device,
                &gpu.queue,
                &cache,
                Settings {
                    output_format: format,
                    ..Settings::default()
                },
            )
            .err()
        });
        assert!(result.is_none(), "{format:?}: {result:?}");
        assert!(error.is_none(), "{format:?}: {error:?}");
    }
}

/// The output may be the settings' format or its sRGB twin (`encode`'s documentation): for
/// each of the four Rgba8/Bgra8 pairs, either way round, the composite writes the twin with
/// no validation error (its render pipeline was built for the settings' format while the pass
/// wrote a view in the texture's own: `Ok`, then "Render pipeline targets are incompatible
/// with render pass", which invalidated the caller's encoder), and the image matches the
/// settings' own format read back (the sRGB twin decoded: within 1/255 plus the sRGB curve's
/// rounding at 8 bits, 2/255 in all).
#[test]
fn an_output_in_the_srgb_twin_of_the_settings_format_is_written() {
    use wgpu::TextureFormat as F;
    let rig = rig(16);
    let device = &rig.gpu.device;
    let medium = medium();
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    let decode = |v: u8, srgb: bool| {
        let c = f32::from(v) / 255.0;
        if !srgb {
            c
        } else if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let read = |target: &wgpu::Texture| -> Vec<f32> {
        let bytes = rig.gpu.read_texture_bytes(target).unwrap();
        let bgra = matches!(target.format(), F::Bgra8Unorm | F::Bgra8UnormSrgb);
        bytes
            .chunks(4)
            .flat_map(|p| {
                let p = if bgra {
                    [p[2], p[1], p[0], p[3]]
                } else {
                    [p[0], p[1], p[2], p[3]]
                };
                p.map(|v| decode(v, target.format().is_srgb()))
            })
            .collect()
    };
    for (settings_format, output_format) in [
        (F::Rgba8Unorm, F::Rgba8UnormSrgb),
        (F::Rgba8UnormSrgb, F::Rgba8Unorm),
        (F::Bgra8Unorm, F::Bgra8UnormSrgb),
        (F::Bgra8UnormSrgb, F::Bgra8Unorm),
    ] {
        let mut vs = VolumetricShadows::new(
            device,
            &rig.gpu.queue,
            &rig.cache,
            Settings {
                output_format: settings_format,
                ..settings()
            },
        )
        .unwrap();
        let mut images = Vec::new();
        for format in [settings_format, output_format] {
            let target = texture(
                &rig.gpu,
                format,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                (rig.size, rig.size, 1),
                1,
            );
            let (result, error) = scoped(device, || {
                vs.prepare(device, &rig.gpu.queue, &frame(&rig, &lights, &medium, &[]))?;
                let mut encoder = device.create_command_encoder(&Default::default());
                vs.encode(&mut encoder, &target)?;
                rig.gpu.submit_and_wait(encoder)
            });
            assert!(
                result.is_ok(),
                "{settings_format:?} into {format:?}: {result:?}"
            );
            assert!(
                error.is_none(),
                "{settings_format:?} into {format:?}: {error:?}"
            );
            images.push(read(&target));
        }
        let diff = images[0]
            .iter()
            .zip(&images[1])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f32::max);
        let mean = images[1].iter().sum::<f32>() / images[1].len() as f32;
        println!("{settings_format:?} settings into {output_format:?}: max diff {diff:.4}, mean {mean:.3}");
        assert!(mean > 0.05, "{output_format:?}: a dark image tests nothing");
        assert!(
            diff <= 2.0 / 255.0,
            "{settings_format:?} into {output_format:?}: {diff}"
        );
    }
}

/// The output may not be a light's own texture (an input of the frame, which the composite
/// does not read): it was accepted, written over and its mips never rebuilt. Refused by
/// `encode` and by `encode_step` of the composite, with nothing recorded; another texture of
/// the same kind is written.
#[test]
fn a_lights_texture_as_the_output_is_refused() {
    let rig = rig(16);
    let device = &rig.gpu.device;
    let medium = medium();
    let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT;
    let make = || {
        texture(
            &rig.gpu,
            wgpu::TextureFormat::Rgba16Float,
            usage,
            (16, 16, 1),
            1,
        )
    };
    let (mask, other) = (make(), make());
    let lights = [FrameLight {
        light: SpotLight::new(
            Vec3::new(0.0, 4.0, 0.0),
            Vec3::NEG_Y,
            1.0,
            Vec3::splat(20.0),
        )
        .unwrap()
        .into(),
        texture: Some(&mask),
        casters: None,
        texture_channels: Default::default(),
    }];
    let settings = Settings {
        output_format: wgpu::TextureFormat::Rgba16Float,
        ..settings()
    };
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings).unwrap();
    let plan = vs
        .prepare(device, &rig.gpu.queue, &frame(&rig, &lights, &medium, &[]))
        .unwrap();
    let composite = plan
        .steps
        .iter()
        .position(|s| s.pass == volshadow::plan::Pass::Composite)
        .expect("a composite step");
    let (results, error) = scoped(device, || {
        let mut encoder = device.create_command_encoder(&Default::default());
        let whole = vs.encode(&mut encoder, &mask).err();
        let step = vs.encode_step(&mut encoder, &mask, composite).err();
        let fine = vs.encode(&mut encoder, &other);
        rig.gpu.submit_and_wait(encoder).unwrap();
        (whole, step, fine)
    });
    for result in [results.0, results.1] {
        match result {
            Some(Error::InvalidTexture {
                field: "output",
                problem,
            }) => {
                assert!(problem.contains("light textures"), "{problem}")
            }
            other => panic!("expected the output refused, got {other:?}"),
        }
    }
    results.2.unwrap();
    assert!(error.is_none(), "{error:?}");
}

/// `read_texture_bytes` (and so `read_rgba32f`) of a texture without `COPY_SRC`, and
/// `read_buffer_bytes` of a buffer without it, are typed errors with nothing recorded (they
/// were `Ok` with garbage and a validation error).
#[test]
fn reading_back_without_copy_src_is_a_typed_error() {
    let gpu = volshadow_harness::gpu();
    let no_copy = texture(
        &gpu,
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
        (4, 4, 1),
        1,
    );
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::UNIFORM,
        mapped_at_creation: false,
    });
    let (results, error) = scoped(&gpu.device, || {
        [
            gpu.read_rgba32f(&no_copy).err(),
            gpu.read_texture_bytes(&no_copy).err(),
            gpu.read_buffer_bytes(&buffer).err(),
        ]
    });
    for result in results {
        match result {
            Some(Error::Readback(problem)) => assert!(problem.contains("COPY_SRC"), "{problem}"),
            other => panic!("expected a readback error, got {other:?}"),
        }
    }
    assert!(error.is_none(), "{error:?}");
}

/// An occluder mesh made on another device of the same adapter: `Ok`, with a validation error
/// (a buffer of another device in a bind group). Refused by `prepare` with a typed error naming
/// the mesh, nothing recorded; the same mesh made on this device renders. (Devices of two
/// separate `wgpu::Instance`s number their resources alike, and wgpu's public API cannot tell
/// them apart: see `OccluderMesh`.)
#[test]
fn an_occluder_mesh_from_another_device_is_a_typed_error() {
    let rig = rig(16);
    let device = &rig.gpu.device;
    let (other_device, _other_queue) =
        pollster::block_on(rig.gpu.adapter.request_device(&Default::default())).unwrap();
    let medium = medium();
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    let sphere = shapes::uv_sphere(Vec3::new(0.0, 1.0, 0.0), 0.4, 16, 8).unwrap();
    let foreign = OccluderMesh::new(&other_device, &sphere);
    let own = OccluderMesh::new(device, &sphere);
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    let (result, error) = scoped(device, || {
        let occluders = [Occluder {
            mesh: &foreign,
            transform: Mat4::IDENTITY,
        }];
        vs.prepare(
            device,
            &rig.gpu.queue,
            &frame(&rig, &lights, &medium, &occluders),
        )
        .err()
    });
    match result {
        Some(Error::InvalidBuffer { field, problem }) => {
            assert_eq!(field, "occluder.mesh");
            assert!(problem.contains("another wgpu::Device"), "{problem}");
        }
        other => panic!("expected the mesh refused, got {other:?}"),
    }
    assert!(error.is_none(), "{error:?}");
    let occluders = [Occluder {
        mesh: &own,
        transform: Mat4::IDENTITY,
    }];
    let target = output(&rig.gpu, rig.size, 1);
    render(
        &rig,
        &mut vs,
        &frame(&rig, &lights, &medium, &occluders),
        (&target).into(),
    );
}

#[test]
fn a_layered_light_texture_is_a_typed_error() {
    let rig = rig(16);
    let device = &rig.gpu.device;
    let medium = medium();
    let layered = texture(
        &rig.gpu,
        wgpu::TextureFormat::Rgba16Float,
        wgpu::TextureUsages::TEXTURE_BINDING,
        (8, 8, 2),
        1,
    );
    let lights = [FrameLight {
        light: SpotLight::new(
            Vec3::new(0.0, 4.0, 0.0),
            Vec3::NEG_Y,
            1.0,
            Vec3::splat(20.0),
        )
        .unwrap()
        .into(),
        texture: Some(&layered),
        casters: None,
        texture_channels: Default::default(),
    }];
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    let (result, error) = scoped(device, || {
        vs.prepare(device, &rig.gpu.queue, &frame(&rig, &lights, &medium, &[]))
            .err()
    });
    match result {
        Some(Error::InvalidTexture {
            field: "light_texture",
            problem,
        }) => assert!(problem.contains("2 array layers"), "{problem}"),
        other => panic!("{other:?}"),
    }
    assert!(error.is_none(), "{error:?}");
}

#[test]
fn occluders_beyond_the_volume_buffer_limit_are_a_typed_error_and_the_next_frame_works() {
    let rig = rig(32);
    let device = &rig.gpu.device;
    let medium = medium();
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    // 540 instances of a 528-triangle sphere (792 edges): 540 · 6 · (792 + 528) volume
    // vertices of 64 bytes (position, flags, the face's plane and a point of it) = 274 MB,
    // beyond the default 128 MiB storage binding.
    let small = OccluderMesh::new(
        device,
        &shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.05, 24, 12).unwrap(),
    );
    assert_eq!(small.summary().triangles, 528);
    let many: Vec<Occluder> = (0..540)
        .map(|i| Occluder {
            mesh: &small,
            transform: Mat4::from_translation(Vec3::new(
                (i % 30) as f32 * 0.1 - 1.5,
                0.0,
                (i / 30) as f32 * 0.1 - 1.0,
            )),
        })
        .collect();
    let one = [Occluder {
        mesh: &small,
        transform: Mat4::from_scale(Vec3::splat(8.0))
            * Mat4::from_translation(Vec3::new(0.0, -1.75, 0.0)),
    }];
    let out = output(&rig.gpu, rig.size, 1);
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    render(
        &rig,
        &mut vs,
        &frame(&rig, &lights, &medium, &one),
        (&out).into(),
    );
    let before = rig.gpu.read_rgba32f(&out).unwrap();

    let (result, error) = scoped(device, || {
        let r = vs
            .prepare(
                device,
                &rig.gpu.queue,
                &frame(&rig, &lights, &medium, &many),
            )
            .err();
        let mut encoder = device.create_command_encoder(&Default::default());
        let encoded = vs.encode(&mut encoder, &out);
        rig.gpu.submit_and_wait(encoder).unwrap();
        (r, encoded)
    });
    let (result, encoded) = result;
    match result {
        Some(Error::DeviceLimitExceeded {
            limit: "max_storage_buffer_binding_size",
            needed,
            max,
            ..
        }) => assert!(
            needed > max && needed == 540 * 6 * (792 + 528) * 64,
            "{needed} {max}"
        ),
        other => panic!("{other:?}"),
    }
    assert!(not_prepared(encoded.clone()), "{encoded:?}");
    assert!(error.is_none(), "validation error: {error:?}");

    // The next valid frame renders as before, without a validation error.
    let (_, error) = scoped(device, || {
        render(
            &rig,
            &mut vs,
            &frame(&rig, &lights, &medium, &one),
            (&out).into(),
        )
    });
    assert!(error.is_none(), "validation error: {error:?}");
    let after = rig.gpu.read_rgba32f(&out).unwrap();
    assert_eq!(max_abs_diff(&after, &before), 0.0);
}

#[test]
fn a_mesh_beyond_the_buffer_size_limit_is_a_typed_error() {
    let rig = rig(16);
    let device = &rig.gpu.device;
    let medium = medium();
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    // 540 × 540 segments: 582k triangles, 873k edges: 279 MB of volume, beyond both the
    // 128 MiB binding and the 256 MiB buffer limits (the binding is named first).
    let big = OccluderMesh::new(
        device,
        &shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.5, 540, 540).unwrap(),
    );
    let occluders = [Occluder {
        mesh: &big,
        transform: Mat4::IDENTITY,
    }];
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    let (result, error) = scoped(device, || {
        vs.prepare(
            device,
            &rig.gpu.queue,
            &frame(&rig, &lights, &medium, &occluders),
        )
        .err()
    });
    assert!(
        matches!(
            result,
            Some(Error::DeviceLimitExceeded {
                field: "shadow volumes",
                ..
            })
        ),
        "{result:?}"
    );
    assert!(error.is_none(), "validation error: {error:?}");
}

/// A light with a radius renders soft shadows (`tests/gpu/soft.rs` measures them): the facade
/// accepts it (it was refused with `InvalidSetting` naming `lights[].radius` while only the
/// reference drew them).
#[test]
fn a_light_with_a_radius_is_accepted() {
    let rig = rig(16);
    let medium = medium();
    let soft = Light::from(
        PointLight::new(Vec3::new(0.0, 3.0, 0.0), Vec3::splat(30.0))
            .unwrap()
            .with_radius(0.2)
            .unwrap(),
    );
    let lights = [FrameLight::from(soft)];
    let f = frame(&rig, &lights, &medium, &[]);
    let mut vs =
        VolumetricShadows::new(&rig.gpu.device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    let result = vs.prepare(&rig.gpu.device, &rig.gpu.queue, &f).map(|_| ());
    assert!(result.is_ok(), "{result:?}");
    // Radius 0 is today's hard light and works.
    let hard = [point(Vec3::new(0.0, 3.0, 0.0))];
    assert!(vs
        .prepare(
            &rig.gpu.device,
            &rig.gpu.queue,
            &frame(&rig, &hard, &medium, &[])
        )
        .is_ok());
}

/// The test adapter's device with storage buffers limited to 1 MiB (bindings) and 4 MiB
/// (buffers): what a large frame meets at the core limits (128 MiB, 256 MiB), at test sizes.
fn small_buffers() -> HeadlessGpu {
    let gpu = volshadow_harness::gpu();
    let required_limits = wgpu::Limits {
        max_storage_buffer_binding_size: 1 << 20,
        max_buffer_size: 4 << 20,
        ..wgpu::Limits::default()
    };
    let (device, queue) = pollster::block_on(gpu.adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("small buffers"),
        required_features: wgpu::Features::empty(),
        required_limits,
        experimental_features: wgpu::ExperimentalFeatures::disabled(),
        memory_hints: wgpu::MemoryHints::Performance,
        trace: wgpu::Trace::Off,
    }))
    .expect("a device with lower limits");
    HeadlessGpu {
        instance: gpu.instance.clone(),
        adapter: gpu.adapter.clone(),
        device,
        queue,
    }
}

/// `prepare`'s error for a frame, with no validation error behind it.
fn prepare_error(
    rig: &Rig,
    vs: &mut VolumetricShadows,
    lights: &[FrameLight<'_>],
    medium: &Medium,
    occluders: &[Occluder<'_>],
) -> Option<Error> {
    let device = &rig.gpu.device;
    let (result, error) = scoped(device, || {
        vs.prepare(
            device,
            &rig.gpu.queue,
            &frame(rig, lights, medium, occluders),
        )
        .err()
    });
    assert!(error.is_none(), "validation error: {error:?}");
    result
}

/// Every buffer beyond a device limit is one error, `DeviceLimitExceeded`, naming the buffer
/// and the limit: the exact method's crossing lists (16 bytes a pixel of heads, bound whole:
/// 4096² at full resolution at the core 128 MiB, 272² at this device's 1 MiB) were
/// `InvalidSetting { field: "extents size" }`, and a soft light's grid list
/// `InvalidSetting { field: "soft shadow size" }`, where the shadow volumes were already
/// `DeviceLimitExceeded`. A frame that fits exactly (256²: 1 MiB of heads) renders, with no
/// validation error either way. The F′ table's cells (16 bytes each, (256 + 11) × 256 at the
/// default size: 1,093,632 bytes) are beyond 1 MiB too, so the frames here use a table of
/// 128 × 256 entries (569,344 bytes), and the default table is checked on its own.
#[test]
fn every_buffer_beyond_a_device_limit_is_device_limit_exceeded() {
    let medium = medium();
    let settings = || Settings {
        table: TableSize {
            along_ray: 128,
            across_rays: 256,
        },
        ..settings()
    };
    let big = rig_on(small_buffers(), 272);
    let device = &big.gpu.device;
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    let sphere = OccluderMesh::new(
        device,
        &shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.5, 16, 8).unwrap(),
    );
    let occluders = [Occluder {
        mesh: &sphere,
        transform: Mat4::IDENTITY,
    }];
    let mut vs = VolumetricShadows::new(device, &big.gpu.queue, &big.cache, settings()).unwrap();
    match prepare_error(&big, &mut vs, &lights, &medium, &occluders) {
        Some(Error::DeviceLimitExceeded {
            field: "crossing lists",
            limit: "max_storage_buffer_binding_size",
            needed,
            max,
        }) => assert_eq!((needed, max), (16 * 272 * 272, 1 << 20)),
        other => panic!("272² crossing lists: {other:?}"),
    }

    // 256²: the heads are exactly 1 MiB, and it renders.
    let fits = rig_on(big.gpu, 256);
    let device = &fits.gpu.device;
    let out = output(&fits.gpu, fits.size, 1);
    let mut vs = VolumetricShadows::new(device, &fits.gpu.queue, &fits.cache, settings()).unwrap();
    let (_, error) = scoped(device, || {
        render(
            &fits,
            &mut vs,
            &frame(&fits, &lights, &medium, &occluders),
            (&out).into(),
        )
    });
    assert!(error.is_none(), "validation error: {error:?}");
    assert!(
        vs.plan()
            .steps
            .iter()
            .any(|s| s.pass == volshadow::plan::Pass::Extents),
        "{}",
        vs.plan()
    );

    // The default F′ table: its cells are beyond 1 MiB.
    let mut vs = VolumetricShadows::new(
        device,
        &fits.gpu.queue,
        &fits.cache,
        Settings {
            table: TableSize::default(),
            ..settings()
        },
    )
    .unwrap();
    match prepare_error(&fits, &mut vs, &lights, &medium, &occluders) {
        Some(Error::DeviceLimitExceeded {
            field: "airlight table cells",
            limit: "max_storage_buffer_binding_size",
            needed,
            max,
        }) => assert_eq!((needed, max), (16 * (256 + 11) * 256, 1 << 20)),
        other => panic!("default F' table: {other:?}"),
    }

    // A soft light's grid: 64² directions × 16 slices × 6 cube layers need a list of
    // 4 · (64² − 32²) · 96 bytes to build, beyond 1 MiB.
    let soft = [FrameLight::from(Light::from(
        PointLight::new(Vec3::new(0.4, 4.5, -0.5), Vec3::splat(30.0))
            .unwrap()
            .with_radius(0.3)
            .unwrap(),
    ))];
    let mut vs = VolumetricShadows::new(device, &fits.gpu.queue, &fits.cache, settings()).unwrap();
    match prepare_error(&fits, &mut vs, &soft, &medium, &occluders) {
        Some(Error::DeviceLimitExceeded {
            field: "soft shadow list",
            limit: "max_storage_buffer_binding_size",
            needed,
            max,
        }) => assert_eq!((needed, max), (4 * (64 * 64 - 32 * 32) * 96, 1 << 20)),
        other => panic!("soft grid list: {other:?}"),
    }
}

/// A scale beyond f32 is reported as such, not as a singular matrix (a uniform scale of 1e30
/// was `SingularMatrix` "singular or not invertible", determinant `inf`): through the facade
/// (`InvalidTransform` on `occluder.transform`), a scene file's `matrix` and a glTF node's
/// `scale`. A scale of 1e12, whose determinant f32 holds, passes the check.
#[test]
fn a_scale_beyond_f32_is_reported_as_such() {
    let rig = rig(16);
    let device = &rig.gpu.device;
    let medium = medium();
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    let sphere = OccluderMesh::new(
        device,
        &shapes::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.5, 16, 8).unwrap(),
    );
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    for (scale, way) in [(1e30f32, "overflows f32"), (1e-30, "underflows f32")] {
        let occluders = [Occluder {
            mesh: &sphere,
            transform: Mat4::from_scale(Vec3::splat(scale)),
        }];
        let (result, error) = scoped(device, || {
            vs.prepare(
                device,
                &rig.gpu.queue,
                &frame(&rig, &lights, &medium, &occluders),
            )
            .err()
        });
        match result {
            Some(Error::InvalidTransform {
                field: "occluder.transform",
                problem,
            }) => assert!(problem.contains(way), "{scale:e}: {problem}"),
            other => panic!("scale {scale:e}: {other:?}"),
        }
        assert!(error.is_none(), "validation error: {error:?}");

        // The same matrix in a scene file.
        let m = Mat4::from_scale(Vec3::splat(scale)).to_cols_array();
        let text = format!(
            r#"{{"name": "t",
                "camera": {{"eye": [0, 2, 8], "target": [0, 1, 0], "fov_y_degrees": 45, "near": 0.1}},
                "lights": [{{"type": "point", "position": [0, 6, 0], "intensity": 10}}],
                "medium": {{"sigma_s": 0.05}},
                "objects": [{{"shape": {{"type": "box", "center": [0, 1, 0], "half_extents": [1, 1, 1]}},
                              "transform": {{"matrix": {m:?}}}}}]}}"#
        );
        let e =
            volshadow::scene_file::SceneDescription::from_json(&text, std::path::Path::new("."))
                .unwrap_err()
                .to_string();
        assert!(e.contains("objects[0].transform") && e.contains(way), "{e}");
        assert!(!e.contains("invertible"), "{e}");
    }
    // A scale f32 still inverts passes the transform check.
    let occluders = [Occluder {
        mesh: &sphere,
        transform: Mat4::from_scale(Vec3::splat(1e12)),
    }];
    let r = vs.prepare(
        device,
        &rig.gpu.queue,
        &frame(&rig, &lights, &medium, &occluders),
    );
    assert!(r.is_ok(), "{:?}", r.err());
}

/// Textures made on another device of the same adapter, in each of the frame's texture slots
/// and as the output: each is refused with a typed error, nothing recorded and no validation
/// error (they were `Ok` with a validation error, a texture of another device in a bind group
/// or a pass); the own textures then render. A `Cache` of the other device, and a `prepare`
/// on it, are refused too.
#[test]
fn textures_from_another_device_are_typed_errors() {
    let rig = rig(16);
    let device = &rig.gpu.device;
    let (other, other_queue) =
        pollster::block_on(rig.gpu.adapter.request_device(&Default::default())).unwrap();
    let foreign = |format: wgpu::TextureFormat, usage: wgpu::TextureUsages| {
        other.create_texture(&wgpu::TextureDescriptor {
            label: Some("foreign"),
            size: rig.color.size(),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let color = foreign(rig.color.format(), rig.color.usage());
    let depth = foreign(rig.depth.format(), rig.depth.usage());
    let out = foreign(
        wgpu::TextureFormat::Rgba32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    );
    let medium = medium();
    let lights = [point(Vec3::new(0.4, 4.5, -0.5))];
    // A Cache of the other device, and a prepare on it.
    let other_cache = Cache::new(&other);
    match VolumetricShadows::new(device, &rig.gpu.queue, &other_cache, settings()) {
        Err(Error::InvalidSetting { field, .. }) => assert_eq!(field, "cache"),
        other => panic!("expected the cache refused, got {:?}", other.err()),
    }
    let mut vs = VolumetricShadows::new(device, &rig.gpu.queue, &rig.cache, settings()).unwrap();
    match vs.prepare(&other, &other_queue, &frame(&rig, &lights, &medium, &[])) {
        Err(Error::InvalidSetting { field, .. }) => assert_eq!(field, "device"),
        other => panic!("expected the device refused, got {:?}", other.err()),
    }
    for (name, swap) in [("scene_color", 0), ("scene_depth", 1)] {
        let (result, error) = scoped(device, || {
            let mut f = frame(&rig, &lights, &medium, &[]);
            if swap == 0 {
                f.scene_color = &color;
            } else {
                f.scene_depth = &depth;
            }
            vs.prepare(device, &rig.gpu.queue, &f).err()
        });
        println!("{name}: {result:?}, {error:?}");
        assert!(error.is_none(), "{name}: {error:?}");
        assert!(
            matches!(
                result,
                Some(Error::Validation {
                    during: "prepare",
                    ..
                })
            ),
            "{name}: {result:?}"
        );
    }
    let mask = foreign(
        wgpu::TextureFormat::Rgba16Float,
        wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let spot = [FrameLight {
        light: SpotLight::new(
            Vec3::new(0.0, 4.0, 0.0),
            Vec3::NEG_Y,
            1.0,
            Vec3::splat(20.0),
        )
        .unwrap()
        .into(),
        texture: Some(&mask),
        casters: None,
        texture_channels: Default::default(),
    }];
    let (result, error) = scoped(device, || {
        vs.prepare(device, &rig.gpu.queue, &frame(&rig, &spot, &medium, &[]))
            .err()
    });
    println!("light texture: {result:?}, {error:?}");
    assert!(error.is_none(), "light texture: {error:?}");
    assert!(
        matches!(
            result,
            Some(Error::Validation {
                during: "prepare",
                ..
            })
        ),
        "light texture: {result:?}"
    );
    let target = output(&rig.gpu, rig.size, 1);
    render(
        &rig,
        &mut vs,
        &frame(&rig, &lights, &medium, &[]),
        (&target).into(),
    );
    vs.prepare(device, &rig.gpu.queue, &frame(&rig, &lights, &medium, &[]))
        .unwrap();
    let (result, error) = scoped(device, || {
        let mut encoder = device.create_command_encoder(&Default::default());
        let r = vs.encode(&mut encoder, &out).err();
        drop(encoder.finish());
        r
    });
    println!("output: {result:?}, {error:?}");
    assert!(error.is_none(), "output: {error:?}");
    match result {
        Some(Error::Validation { during, message }) => {
            assert!(during.starts_with("encode"), "{during}");
            assert!(message.contains("match Device"), "{message}");
        }
        other => panic!("expected the output refused, got {other:?}"),
    }
    render(
        &rig,
        &mut vs,
        &frame(&rig, &lights, &medium, &[]),
        (&target).into(),
    );
}
