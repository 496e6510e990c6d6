//! Textured spot lights against the f64 reference (issue 4): a coloured checkerboard projected
//! through fog past a sphere occluder, each march step reading the texture's mip level whose
//! footprint matches the step.

use crate::common;
use volshadow::nodes::Node;

use glam::{DVec3, Mat4, Vec3};
use volshadow::gpu::{Occluder, OccluderMesh};
use volshadow::nodes::{LightTextureNode, MarchSettings};
use volshadow::reference::{self, TexturedSpot, TriangleMesh};
use volshadow::scene::{shapes, LightTexture};
use volshadow::{Error, Light, Medium, PhaseFunction, SpotLight};

const SIZE: u32 = 128;
/// A textured spot's in-scatter RMSE against the reference, relative to the mean: the 2% of
/// untextured lights plus room for the bilinear texture's kinks between texel centres.
const MAX_RMSE: f64 = 0.03;

fn ground(o: DVec3, d: DVec3) -> f64 {
    if d.y < 0.0 {
        -o.y / d.y
    } else {
        f64::INFINITY
    }
}

/// The scene of this file: a spot above a sphere (centre 0, 2.2, 0; radius 0.5) over a
/// ground, a coloured checkerboard, and the camera looking at the sphere.
struct Rig {
    spot: SpotLight,
    texture: LightTexture,
    camera: volshadow::Camera,
    center: Vec3,
}

fn rig() -> Rig {
    Rig {
        spot: SpotLight::new(
            Vec3::new(0.3, 4.0, -0.2),
            Vec3::new(-0.1, -1.0, 0.05),
            60f32.to_radians(),
            Vec3::splat(80.0),
        )
        .unwrap(),
        texture: LightTexture::checkerboard(
            64,
            8,
            Vec3::new(1.0, 0.25, 0.1),
            Vec3::new(0.1, 0.35, 1.0),
        )
        .unwrap(),
        camera: common::look_at(
            Vec3::new(0.0, 1.6, 5.5),
            Vec3::new(0.0, 1.5, 0.0),
            60.0,
            1.0,
        ),
        center: Vec3::new(0.0, 2.2, 0.0),
    }
}

/// The GPU in-scatter of `light` with the rig's texture over a ground, `mesh` the occluder,
/// `size`² pixels, at the default march settings (64 steps in the extents, 32 before and
/// after).
fn textured_inscatter(
    rig: &Rig,
    light: &Light,
    medium: &Medium,
    mesh: &volshadow::scene::Mesh,
    size: u32,
) -> Vec<[f32; 4]> {
    let gpu = common::gpu();
    let cache = common::cache(&gpu);
    let depths = common::depths_at(&rig.camera, size, size, ground);
    let depth = common::depth_texture(&gpu, size, size, &depths);
    let gpu_mesh = OccluderMesh::new(&gpu.device, mesh);
    let occluders = [Occluder {
        mesh: &gpu_mesh,
        transform: Mat4::IDENTITY,
    }];
    let uploaded = rig.texture.upload(&gpu.device, &gpu.queue);
    let passes = common::ShadowPasses::new(&rig.camera, light, medium, &depth, &occluders)
        .settings(MarchSettings::default())
        .texture(Some(&uploaded));
    common::shadow_frame(&gpu, &cache, &passes).inscatter
}

/// RMSE of the GPU in-scatter against the reference, relative to the reference's mean.
fn textured_rmse(medium: &Medium) -> f64 {
    let rig = rig();
    let Rig {
        spot,
        ref texture,
        camera,
        center,
    } = rig;
    let mesh = shapes::uv_sphere(center, 0.5, 24, 12).unwrap();
    let inscatter = textured_inscatter(&rig, &Light::from(spot), medium, &mesh, SIZE);
    assert!(inscatter
        .iter()
        .all(|t| t[0..3].iter().all(|v| v.is_finite() && *v >= 0.0)));

    let textured = TexturedSpot { spot, texture };
    let ref_occ = [reference::Occluder::Mesh(TriangleMesh::from_indexed(
        mesh.positions(),
        mesh.indices(),
        glam::DMat4::IDENTITY,
    ))];
    let reference =
        reference::inscatter_image(&camera, SIZE, SIZE, ground, medium, &textured, &ref_occ);
    let (mut sq, mut sum) = (0.0, 0.0);
    for (g, r) in inscatter.iter().zip(&reference) {
        for c in 0..3 {
            sq += (f64::from(g[c]) - r[c]).powi(2);
            sum += r[c];
        }
    }
    let n = 3.0 * reference.len() as f64;
    // The texture matters: a uniform white texture gives a clearly different image.
    let plain = reference::inscatter_image(&camera, SIZE, SIZE, ground, medium, &spot, &ref_occ);
    let plain_sq: f64 = plain
        .iter()
        .zip(&reference)
        .map(|(p, r)| (0..3).map(|c| (p[c] - r[c]).powi(2)).sum::<f64>())
        .sum();
    let plain_rmse = (plain_sq / n).sqrt() / (sum / n);
    assert!(
        plain_rmse > 0.1,
        "the texture should change the image, RMSE without it {plain_rmse:.3}"
    );
    (sq / n).sqrt() / (sum / n)
}

#[test]
fn checkerboard_spot_matches_reference() {
    let medium = Medium::new(
        Vec3::new(0.2, 0.22, 0.25),
        Vec3::splat(0.03),
        PhaseFunction::HenyeyGreenstein { g: 0.5 },
    )
    .unwrap();
    let rmse = textured_rmse(&medium);
    println!("textured spot, HG 0.5: RMSE {rmse:.4} of mean");
    common::metric::accuracy(
        "checkerboard textured spot, HG 0.5",
        format!("RMSE {:.2}%", 100.0 * rmse),
        format!("RMSE {}%", 100.0 * MAX_RMSE),
    );
    // Issue 4: in-scatter RMSE ≤ 3% of the mean against the reference.
    assert!(rmse <= MAX_RMSE, "RMSE {rmse:.4}");
}

#[test]
fn checkerboard_spot_hoffman_preetham_matches_reference() {
    let medium = Medium::hoffman_preetham(
        Vec3::new(0.05, 0.09, 0.2),
        Vec3::new(0.12, 0.12, 0.12),
        0.75,
        Vec3::splat(0.01),
    )
    .unwrap();
    let rmse = textured_rmse(&medium);
    println!("textured spot, Hoffman-Preetham: RMSE {rmse:.4} of mean");
    common::metric::accuracy(
        "checkerboard textured spot, Hoffman–Preetham",
        format!("RMSE {:.2}%", 100.0 * rmse),
        format!("RMSE {}%", 100.0 * MAX_RMSE),
    );
    assert!(rmse <= MAX_RMSE, "RMSE {rmse:.4}");
}

#[test]
fn invalid_spot_and_texture_inputs_are_errors() {
    let p = Vec3::new(0.0, 3.0, 0.0);
    for angle in [0.0, -0.5, std::f32::consts::PI, 4.0] {
        assert_eq!(
            SpotLight::new(p, Vec3::NEG_Y, angle, Vec3::ONE),
            Err(Error::ConeAngleOutOfRange {
                angle,
                max: SpotLight::MAX_CONE_ANGLE
            })
        );
    }
    assert!(matches!(
        SpotLight::new(p, Vec3::ZERO, 1.0, Vec3::ONE),
        Err(Error::DegenerateDirection { .. })
    ));
    assert!(matches!(
        LightTexture::new(0, 4, vec![]),
        Err(Error::InvalidSize {
            field: "light texture",
            ..
        })
    ));
    assert!(matches!(
        LightTexture::new(2, 2, vec![Vec3::ONE; 3]),
        Err(Error::InvalidTexture { .. })
    ));
    assert!(matches!(
        LightTexture::new(1, 1, vec![Vec3::new(-1.0, 0.0, 0.0)]),
        Err(Error::Negative { .. })
    ));

    // A texture that cannot be filtered: a typed error, no wgpu validation error.
    let gpu = common::gpu();
    let cache = common::cache(&gpu);
    let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let mut node = LightTextureNode::new(&gpu.device, &cache).unwrap();
    for format in [
        wgpu::TextureFormat::R32Uint,
        wgpu::TextureFormat::Rgba32Float,
    ] {
        let t = common::texture(
            &gpu,
            format,
            wgpu::TextureUsages::TEXTURE_BINDING,
            (4, 4, 1),
            1,
        );
        let err = node.prepare(&gpu.device, &gpu.queue, &t).err();
        assert!(
            matches!(
                err,
                Some(Error::InvalidTexture {
                    field: "light_texture",
                    ..
                })
            ),
            "{format:?}: {err:?}"
        );
    }
    assert!(pollster::block_on(scope.pop()).is_none());
}

/// A textured spot with a radius (0.3, a sixth of its distance to the sphere): soft shadows
/// through the grid, the texture projected from the light's centre, against the reference's
/// visible fraction of the disc times the texture (64², exact sphere in the reference). Bars:
/// p95 3% (the soft tests'), RMSE 3% (the textured spot's, above). The same frame drawn hard
/// is beyond 10% p95, and its RMSE against the hard reference is the texture's own error at
/// this resolution. Measured p95 1.56%, RMSE 2.25%; with the grid's value alone at each step
/// (the marks for an occluder's surface ignored), RMSE 4.18% (fails), max 18%: the bars tell.
#[test]
fn soft_textured_spot_against_the_reference() {
    const SOFT_SIZE: u32 = 64;
    let medium = Medium::new(
        Vec3::new(0.2, 0.22, 0.25),
        Vec3::splat(0.03),
        PhaseFunction::HenyeyGreenstein { g: 0.5 },
    )
    .unwrap();
    let rig = rig();
    let Rig {
        spot,
        ref texture,
        camera,
        center,
    } = rig;
    let spot = spot.with_radius(0.3).unwrap();
    let mesh = shapes::uv_sphere(center, 0.5, 64, 32).unwrap();
    let render = |light: &Light| textured_inscatter(&rig, light, &medium, &mesh, SOFT_SIZE);
    let textured = TexturedSpot { spot, texture };
    let ref_occ = [reference::Sphere::new(center.as_dvec3(), 0.5).into()];
    let reference = reference::soft::inscatter_image_soft(
        &camera, SOFT_SIZE, SOFT_SIZE, ground, &medium, &textured, &ref_occ,
    );
    let light = Light::from(spot);
    let soft = common::scene::errors(
        &render(&light),
        &reference,
        &camera,
        &light,
        (SOFT_SIZE, SOFT_SIZE),
    );
    let hard_light = Light::from(spot.with_radius(0.0).unwrap());
    let hard = common::scene::errors(
        &render(&hard_light),
        &reference,
        &camera,
        &light,
        (SOFT_SIZE, SOFT_SIZE),
    );
    // The texture's own error at this resolution: the hard frame against the hard reference.
    let hard_spot = spot.with_radius(0.0).unwrap();
    let hard_reference = reference::inscatter_image(
        &camera,
        SOFT_SIZE,
        SOFT_SIZE,
        ground,
        &medium,
        &TexturedSpot {
            spot: hard_spot,
            texture,
        },
        &ref_occ,
    );
    let hard_own = common::scene::errors(
        &render(&hard_light),
        &hard_reference,
        &camera,
        &hard_light,
        (SOFT_SIZE, SOFT_SIZE),
    );
    eprintln!(
        "soft textured spot: {soft}\n  hard against the soft reference: {hard}\n  hard \
         against the hard reference: {hard_own}"
    );
    common::metric::accuracy(
        "textured spot of radius 0.3, soft through the grid, 64²; drawn hard against the soft reference",
        format!("{}; hard p95 {:.1}%", soft.short(), 100.0 * hard.p95),
        format!("p95 3%, RMSE {}%; hard p95 > 10%", 100.0 * MAX_RMSE),
    );
    assert_eq!(soft.non_finite, 0);
    assert!(
        soft.p95 <= 0.03 && soft.rmse <= MAX_RMSE,
        "soft textured spot beyond p95 3%, RMSE {MAX_RMSE}: {soft}"
    );
    // The bars tell a penumbra from none.
    assert!(hard.p95 > 0.1, "hard against the soft reference: {hard}");
}
