//! Every kind of invalid input returns its own error variant, never a panic (issue 2 item 3),
//! and nothing the caller passed is modified.

use volshadow::nodes::Node;

use glam::{Mat4, Vec3};
use volshadow::nodes::{
    AirlightTableNode, CompositeInputs, CompositeNode, MarchInputs, MarchMode, MarchNode,
    MarchSettings, TableSize,
};
use volshadow::{Camera, Error, Medium, PhaseFunction, PointLight};

fn view() -> Mat4 {
    glam::camera::rh::view::look_at_mat4(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, Vec3::Y)
}
fn projection() -> Mat4 {
    glam::camera::rh::proj::directx::perspective(1.0, 1.0, 0.1, 100.0)
}

#[test]
fn nan_coefficient_is_non_finite() {
    let err = Medium::new(
        Vec3::new(0.1, f32::NAN, 0.1),
        Vec3::ZERO,
        PhaseFunction::Isotropic,
    );
    assert!(
        matches!(
            err,
            Err(Error::NonFinite {
                field: "medium.sigma_s",
                ..
            })
        ),
        "{err:?}"
    );
}

#[test]
fn infinite_coefficient_is_non_finite() {
    let err = Medium::new(
        Vec3::splat(0.1),
        Vec3::new(f32::INFINITY, 0.0, 0.0),
        PhaseFunction::Isotropic,
    );
    assert!(
        matches!(
            err,
            Err(Error::NonFinite {
                field: "medium.sigma_a",
                ..
            })
        ),
        "{err:?}"
    );
}

#[test]
fn negative_coefficient_is_negative() {
    let err = Medium::new(
        Vec3::splat(0.1),
        Vec3::new(0.0, -0.01, 0.0),
        PhaseFunction::Isotropic,
    );
    assert_eq!(
        err,
        Err(Error::Negative {
            field: "medium.sigma_a",
            value: -0.01
        })
    );
    let err = Medium::new(Vec3::splat(-1.0), Vec3::ZERO, PhaseFunction::Isotropic);
    assert!(matches!(
        err,
        Err(Error::Negative {
            field: "medium.sigma_s",
            ..
        })
    ));
}

#[test]
fn asymmetry_at_or_beyond_one_is_rejected() {
    for g in [1.0, -1.0, 1.5] {
        let err = Medium::new(
            Vec3::splat(0.1),
            Vec3::ZERO,
            PhaseFunction::HenyeyGreenstein { g },
        );
        assert_eq!(err, Err(Error::AsymmetryOutOfRange { g }));
    }
    let err = Medium::hoffman_preetham(Vec3::splat(0.1), Vec3::splat(0.1), 1.0, Vec3::ZERO);
    assert_eq!(err, Err(Error::AsymmetryOutOfRange { g: 1.0 }));
    let err = Medium::new(
        Vec3::splat(0.1),
        Vec3::ZERO,
        PhaseFunction::HenyeyGreenstein { g: f32::NAN },
    );
    assert!(matches!(
        err,
        Err(Error::NonFinite {
            field: "phase.g",
            ..
        })
    ));
}

#[test]
fn hoffman_preetham_without_weight_in_a_channel_is_rejected() {
    let err = Medium::hoffman_preetham(
        Vec3::new(0.1, 0.0, 0.1),
        Vec3::new(0.1, 0.0, 0.1),
        0.7,
        Vec3::ZERO,
    );
    assert!(
        matches!(err, Err(Error::ZeroPhaseWeight { channel: 1, .. })),
        "{err:?}"
    );
    let err =
        Medium::hoffman_preetham(Vec3::new(0.1, -0.1, 0.1), Vec3::splat(0.1), 0.7, Vec3::ZERO);
    assert!(
        matches!(
            err,
            Err(Error::Negative {
                field: "phase.rayleigh",
                ..
            })
        ),
        "{err:?}"
    );
}

#[test]
fn zero_intensity_is_rejected() {
    let err = PointLight::new(Vec3::ONE, Vec3::ZERO);
    assert_eq!(
        err,
        Err(Error::ZeroIntensity {
            field: "point_light.intensity"
        })
    );
    let err = PointLight::new(Vec3::ONE, Vec3::new(1.0, -1.0, 0.0));
    assert!(matches!(err, Err(Error::Negative { .. })));
}

#[test]
fn non_finite_light_position_is_rejected() {
    let err = PointLight::new(Vec3::new(0.0, f32::NAN, 0.0), Vec3::ONE);
    assert!(matches!(
        err,
        Err(Error::NonFinite {
            field: "point_light.position",
            ..
        })
    ));
}

#[test]
fn singular_view_matrix_is_rejected() {
    let mut flat = view();
    flat.y_axis = glam::Vec4::ZERO;
    let err = Camera::new(flat, projection());
    assert!(
        matches!(err, Err(Error::SingularMatrix { matrix: "view", .. })),
        "{err:?}"
    );
}

#[test]
fn singular_projection_matrix_is_rejected() {
    let err = Camera::new(view(), Mat4::ZERO);
    assert!(
        matches!(
            err,
            Err(Error::SingularMatrix {
                matrix: "projection",
                ..
            })
        ),
        "{err:?}"
    );
}

#[test]
fn non_finite_matrix_is_rejected() {
    let mut m = view();
    m.w_axis.x = f32::INFINITY;
    let err = Camera::new(m, projection());
    assert!(
        matches!(
            err,
            Err(Error::NonFinite {
                field: "camera.view",
                ..
            })
        ),
        "{err:?}"
    );
}

#[test]
fn orthographic_projection_is_not_perspective() {
    let ortho = glam::camera::rh::proj::directx::orthographic(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0);
    assert_eq!(Camera::new(view(), ortho), Err(Error::NotPerspective));
}

#[test]
fn every_depth_convention_is_accepted_and_detected() {
    use glam::camera::rh::proj::directx as p;
    let cases = [
        (p::perspective(1.0, 1.5, 0.1, 100.0), 1.0),
        (p::perspective(1.0, 1.5, 100.0, 0.1), 0.0), // reversed Z, finite
        (p::perspective_infinite(1.0, 1.5, 0.1), 1.0),
        (p::perspective_infinite_reverse(1.0, 1.5, 0.1), 0.0),
    ];
    for (proj, far) in cases {
        let camera = Camera::new(view(), proj).unwrap();
        assert_eq!(camera.far_depth(), far, "{proj:?}");
        assert!((camera.eye() - Vec3::new(0.0, 1.0, 5.0)).length() < 1e-5);
    }
}

#[test]
fn table_size_below_two_is_rejected() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    for size in [
        TableSize {
            along_ray: 1,
            across_rays: 64,
        },
        TableSize {
            along_ray: 64,
            across_rays: 0,
        },
    ] {
        let err = AirlightTableNode::new(&gpu.device, &cache, size).err();
        assert!(
            matches!(
                err,
                Some(Error::InvalidSize {
                    field: "airlight table size",
                    ..
                })
            ),
            "{err:?}"
        );
    }
}

#[test]
fn bad_textures_are_typed_errors_not_validation_errors() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let camera = Camera::new(view(), projection()).unwrap();
    let light = volshadow::Light::from(PointLight::new(Vec3::Y, Vec3::ONE).unwrap());
    let medium = Medium::new(Vec3::splat(0.1), Vec3::ZERO, PhaseFunction::Isotropic).unwrap();
    let tex = |format, usage, w, h| volshadow_harness::texture(&gpu, format, usage, (w, h, 1), 1);
    let sampled = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::RENDER_ATTACHMENT;
    let table = AirlightTableNode::new(&gpu.device, &cache, TableSize::default()).unwrap();
    let mut march = MarchNode::new(&gpu.device, &cache, MarchSettings::default()).unwrap();
    let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);

    // A colour texture passed as depth.
    let colour = tex(wgpu::TextureFormat::Rgba8Unorm, sampled, 16, 16);
    let inputs = MarchInputs {
        camera: &camera,
        light: &light,
        medium: &medium,
        table: &table,
        scene_depth: &colour,
        shadows: None,
        mode: MarchMode::Analytic,
        light_texture: None,
    };
    let err = march.prepare(&gpu.device, &gpu.queue, &inputs).err();
    assert!(
        matches!(
            err,
            Some(Error::InvalidTexture {
                field: "scene_depth",
                ..
            })
        ),
        "{err:?}"
    );

    // A depth texture without TEXTURE_BINDING.
    let unbound = tex(
        wgpu::TextureFormat::Depth32Float,
        wgpu::TextureUsages::RENDER_ATTACHMENT,
        16,
        16,
    );
    let inputs = MarchInputs {
        scene_depth: &unbound,
        ..inputs
    };
    let err = march.prepare(&gpu.device, &gpu.queue, &inputs).err();
    assert!(
        matches!(
            err,
            Some(Error::InvalidTexture {
                field: "scene_depth",
                ..
            })
        ),
        "{err:?}"
    );

    // A mode whose inputs are missing: each shadowed mode without shadows. The analytic mode
    // passes with the same inputs.
    let depth = tex(wgpu::TextureFormat::Depth32Float, sampled, 16, 16);
    for mode in [MarchMode::Exact, MarchMode::Hybrid, MarchMode::BruteForce] {
        let inputs = MarchInputs {
            scene_depth: &depth,
            mode,
            ..inputs
        };
        let err = march.prepare(&gpu.device, &gpu.queue, &inputs).err();
        assert!(
            matches!(err, Some(Error::InvalidSetting { field: "mode", .. })),
            "{mode:?}: {err:?}"
        );
    }
    let inputs = MarchInputs {
        scene_depth: &depth,
        mode: MarchMode::Analytic,
        ..inputs
    };
    march.prepare(&gpu.device, &gpu.queue, &inputs).unwrap();

    // A composite onto a depth format, and with inputs of different sizes.
    let err = CompositeNode::new(&gpu.device, &cache, wgpu::TextureFormat::Depth32Float).err();
    assert!(
        matches!(
            err,
            Some(Error::InvalidTexture {
                field: "output_format",
                ..
            })
        ),
        "{err:?}"
    );
    let mut composite =
        CompositeNode::new(&gpu.device, &cache, wgpu::TextureFormat::Rgba16Float).unwrap();
    let depth = tex(wgpu::TextureFormat::Depth32Float, sampled, 16, 16);
    let small = tex(wgpu::TextureFormat::Rgba16Float, sampled, 8, 8);
    let err = composite
        .prepare(
            &gpu.device,
            &gpu.queue,
            &CompositeInputs {
                camera: &camera,
                medium: &medium,
                scene_color: &colour,
                scene_depth: &depth,
                inscatter: &[&small],
                surfaces: None,
            },
        )
        .err();
    assert!(
        matches!(
            err,
            Some(Error::InvalidTexture {
                field: "inscatter",
                ..
            })
        ),
        "{err:?}"
    );
    // Encoding before a successful prepare, or into a wrong-format target, records nothing.
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    let target = tex(wgpu::TextureFormat::Rgba8Unorm, sampled, 16, 16);
    let err = composite
        .encode(&mut encoder, &(&target).into(), None)
        .err();
    assert!(
        matches!(
            err,
            Some(Error::InvalidTexture {
                field: "output",
                ..
            })
        ),
        "{err:?}"
    );
    gpu.queue.submit([encoder.finish()]);

    let validation = pollster::block_on(scope.pop());
    assert!(
        validation.is_none(),
        "wgpu validation error: {validation:?}"
    );
}
