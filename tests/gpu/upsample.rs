//! Low-resolution scattering and bilateral upsampling across a depth edge (issue 4).

use glam::Vec3;
use volshadow::gpu::{Occluder, OccluderMesh};
use volshadow::nodes::{MarchSettings, Scale, UpsampleFilter, UpsampleNode};
use volshadow::scene::shapes;
use volshadow::{Cache, Camera, HeadlessGpu, Light, Medium, PhaseFunction, PointLight};

const SIZE: u32 = 128;
/// The depth edge: columns left of it hold a near occluder, the rest a far wall.
const EDGE: u32 = 61;
/// The largest pull of an upsampled pixel towards the other side of the depth edge: what a
/// depth-aware filter stays under and plain bilinear (about 20%) does not.
const MAX_PULL: f64 = 0.05;

/// Shadowed in-scatter (hybrid, 64 steps) at `scale`, upsampled by `filter` when reduced.
#[allow(clippy::too_many_arguments)]
fn inscatter(
    gpu: &HeadlessGpu,
    cache: &Cache,
    camera: &Camera,
    light: &Light,
    medium: &Medium,
    depth: &wgpu::Texture,
    occluders: &[Occluder],
    scale: Scale,
    filter: UpsampleFilter,
) -> Vec<[f32; 4]> {
    let settings = MarchSettings {
        scale,
        ..Default::default()
    };
    let passes = volshadow_harness::ShadowPasses::new(camera, light, medium, depth, occluders)
        .settings(settings)
        .shadow_resolution(512)
        .filter(filter);
    volshadow_harness::shadow_frame(gpu, cache, &passes).inscatter
}

/// Largest pull towards the other side of the edge among pixels within 3 pixels of it:
/// (upsampled − truth) / (truth across the edge − truth), the truth being full resolution.
fn worst_pull(truth: &[[f32; 4]], test: &[[f32; 4]]) -> f64 {
    let mut worst: f64 = 0.0;
    for y in 0..SIZE {
        for x in EDGE.saturating_sub(3)..(EDGE + 3).min(SIZE) {
            let i = (y * SIZE + x) as usize;
            // The nearest pixel on the other side, in the same row.
            let other = if x < EDGE {
                (y * SIZE + EDGE) as usize
            } else {
                (y * SIZE + EDGE - 1) as usize
            };
            for c in 0..3 {
                let across = f64::from(truth[other][c] - truth[i][c]);
                let moved = f64::from(test[i][c] - truth[i][c]);
                worst = worst.max(moved / across);
            }
        }
    }
    worst
}

#[test]
fn bilateral_filters_do_not_blend_across_a_depth_edge() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let camera = volshadow_harness::look_at(
        Vec3::new(0.0, 1.0, 6.0),
        Vec3::new(0.0, 1.0, 0.0),
        50.0,
        1.0,
    );
    // Dense fog, a light between the eye and the wall (just out of view), and a small box on
    // the line from the light to the eye that puts the eye in shadow: rays stopped by the near
    // occluder stay in the shadow (lit fraction ~0), rays to the far wall leave it (lit
    // fraction ~1) and gather far more in-scatter.
    let light: Light = PointLight::new(Vec3::new(0.0, 2.5, 3.0), Vec3::splat(40.0))
        .unwrap()
        .into();
    let block = OccluderMesh::new(
        &gpu.device,
        &shapes::cuboid(Vec3::new(0.0, 1.75, 4.5), Vec3::splat(0.3)).unwrap(),
    );
    let occluders = [Occluder {
        mesh: &block,
        transform: glam::Mat4::IDENTITY,
    }];
    let medium = Medium::new(
        Vec3::splat(0.12),
        Vec3::splat(0.02),
        PhaseFunction::HenyeyGreenstein { g: 0.4 },
    )
    .unwrap();
    let depths: Vec<f32> = (0..SIZE * SIZE)
        .map(|i| {
            let (x, y) = (i % SIZE, i / SIZE);
            let (eye, dir) = volshadow_harness::pixel_ray(&camera, SIZE, SIZE, x, y);
            // Near occluder: the plane z = 5 (1 from the eye); far wall: z = −12.
            let plane_z = if x < EDGE { 5.0 } else { -12.0 };
            volshadow_harness::ndc_depth(&camera, eye + dir * ((plane_z - eye.z) / dir.z))
        })
        .collect();
    let depth = volshadow_harness::depth_texture(&gpu, SIZE, SIZE, &depths);
    let truth = inscatter(
        &gpu,
        &cache,
        &camera,
        &light,
        &medium,
        &depth,
        &occluders,
        Scale::Full,
        UpsampleFilter::DepthAware3x3,
    );
    let near = truth[(64 * SIZE + EDGE - 1) as usize][0];
    let far = truth[(64 * SIZE + EDGE) as usize][0];
    println!("in-scatter: near side {near:.4}, far side {far:.4}");
    assert!(
        far > 3.0 * near,
        "the edge must separate very different in-scatter"
    );

    // Issue 4: no pixel within 3 pixels of the edge pulled more than 5% toward the other side.
    let filters = [
        ("3x3 depth-aware", UpsampleFilter::DepthAware3x3),
        (
            "separable 7-tap",
            UpsampleFilter::Separable {
                taps: 7,
                sigma_spatial: 1.0,
                sigma_depth: 0.05,
            },
        ),
    ];
    for (name, filter) in filters {
        let up = inscatter(
            &gpu,
            &cache,
            &camera,
            &light,
            &medium,
            &depth,
            &occluders,
            Scale::Quarter,
            filter,
        );
        assert!(up.iter().all(|t| t[0..3].iter().all(|v| v.is_finite())));
        let pull = worst_pull(&truth, &up);
        println!("1/4 resolution + {name}: worst pull across the edge {pull:.4}");
        volshadow_harness::metric::accuracy(
            &format!("depth edge at ¼ resolution, {name}: worst pull across the edge"),
            format!("{:.1}%", 100.0 * pull),
            format!("{}%", 100.0 * MAX_PULL),
        );
        assert!(pull <= MAX_PULL, "{name} pulls {pull:.4} across the edge");
    }
    // Plain bilinear blends across the edge: the same test fails for it.
    let up = inscatter(
        &gpu,
        &cache,
        &camera,
        &light,
        &medium,
        &depth,
        &occluders,
        Scale::Quarter,
        UpsampleFilter::Bilinear,
    );
    let pull = worst_pull(&truth, &up);
    println!("1/4 resolution + plain bilinear: worst pull across the edge {pull:.4}");
    volshadow_harness::metric::accuracy(
        "depth edge at ¼ resolution, plain bilinear (must fail)",
        format!("{:.1}%", 100.0 * pull),
        "> 5%",
    );
    assert!(
        pull > 0.05,
        "plain bilinear should fail the edge test, pulled only {pull:.4}"
    );
}

#[test]
fn invalid_scales_and_filters_are_errors() {
    assert!(matches!(
        Scale::from_divisor(3),
        Err(volshadow::Error::InvalidSetting {
            field: "scattering scale",
            ..
        })
    ));
    assert!(matches!(
        Scale::from_divisor(0),
        Err(volshadow::Error::InvalidSetting { .. })
    ));
    assert_eq!(Scale::from_divisor(4), Ok(Scale::Quarter));
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    for (taps, ss, sz) in [
        (0, 1.0, 0.1),
        (4, 1.0, 0.1),
        (33, 1.0, 0.1),
        (5, 0.0, 0.1),
        (5, 1.0, -1.0),
        (5, f32::NAN, 0.1),
    ] {
        let filter = UpsampleFilter::Separable {
            taps,
            sigma_spatial: ss,
            sigma_depth: sz,
        };
        let err = UpsampleNode::new(&gpu.device, &cache, filter).err();
        assert!(
            matches!(
                err,
                Some(volshadow::Error::InvalidSetting { .. } | volshadow::Error::NonFinite { .. })
            ),
            "{filter:?}: {err:?}"
        );
    }
}
