//! Scene types validated like scene files: an occluder's transform (affine, not mirrored,
//! invertible) and a light texture's texels (within the f16 range they upload in).

use volshadow::nodes::Node;

use std::path::Path;

use glam::{Mat4, Vec3, Vec4};
use volshadow::nodes::{ShadowMapInputs, ShadowMapNode, ShadowMapSettings};
use volshadow::scene::{shapes, LightTexture};
use volshadow::scene_file::SceneDescription;
use volshadow::{Error, Light, Occluder, OccluderMesh, PointLight};

/// A scene file with one box placed by `matrix` (column-major).
fn scene_with_matrix(m: Mat4) -> String {
    format!(
        r#"{{"name": "t",
            "camera": {{"eye": [0, 2, 8], "target": [0, 1, 0], "fov_y_degrees": 45, "near": 0.1}},
            "lights": [{{"type": "point", "position": [0, 6, 0], "intensity": 10}}],
            "medium": {{"sigma_s": 0.05}},
            "objects": [{{"shape": {{"type": "box", "center": [0, 0, 0], "half_extents": [1, 1, 1]}},
                          "transform": {{"matrix": {:?}}}}}]}}"#,
        m.to_cols_array()
    )
}

/// Mirrored, non-affine, singular and nearly flat transforms: each is an error from the shadow
/// map's `prepare` (which validates its occluders) and from a scene file alike; a rotation,
/// translation and non-uniform scale passes both.
#[test]
fn occluder_transform_validated_as_scene_files_do() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let mut node = ShadowMapNode::new(&gpu.device, &cache, ShadowMapSettings::default()).unwrap();
    let mesh = OccluderMesh::new(&gpu.device, &shapes::cuboid(Vec3::ZERO, Vec3::ONE).unwrap());
    let light = Light::Point(PointLight::new(Vec3::new(0.0, 5.0, 0.0), Vec3::ONE).unwrap());
    let mut projective = Mat4::IDENTITY;
    projective.x_axis.w = 0.5;
    let mut shear_row = Mat4::IDENTITY;
    shear_row.w_axis = Vec4::new(1.0, 2.0, 3.0, 2.0);
    let cases = [
        ("mirrored", Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0))),
        (
            "mirrored by rotation and scale",
            Mat4::from_rotation_y(0.3) * Mat4::from_scale(Vec3::new(1.0, 1.0, -2.0)),
        ),
        ("non-affine last row", projective),
        ("non-affine w", shear_row),
        ("singular", Mat4::from_scale(Vec3::new(1.0, 0.0, 1.0))),
        // Y sheared onto X: determinant 1e-14 against column lengths of about 1.4, below the
        // relative 1e-12 of the shared check (a per-axis scale alone is never flat by it).
        (
            "nearly flat",
            Mat4::from_cols(Vec4::X, Vec4::new(1.0, 1e-14, 0.0, 0.0), Vec4::Z, Vec4::W),
        ),
    ];
    for (name, transform) in cases {
        let occluders = [Occluder {
            mesh: &mesh,
            transform,
        }];
        let inputs = ShadowMapInputs {
            light: &light,
            occluders: &occluders,
            camera: &volshadow_harness::unread_camera(),
            fallback: None,
        };
        let got = node.prepare(&gpu.device, &gpu.queue, &inputs);
        assert!(
            matches!(
                got,
                Err(Error::InvalidTransform {
                    field: "occluder.transform",
                    ..
                } | Error::SingularMatrix {
                    matrix: "occluder transform",
                    ..
                })
            ),
            "{name}: {got:?}"
        );
        // The scene file rejects the same matrix.
        let file = SceneDescription::from_json(&scene_with_matrix(transform), Path::new("."));
        assert!(matches!(file, Err(Error::SceneFile(_))), "{name}: {file:?}");
    }
    let good = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0))
        * Mat4::from_rotation_z(0.7)
        * Mat4::from_scale(Vec3::new(0.5, 2.0, 3.0));
    let occluders = [Occluder {
        mesh: &mesh,
        transform: good,
    }];
    let inputs = ShadowMapInputs {
        light: &light,
        occluders: &occluders,
        camera: &volshadow_harness::unread_camera(),
        fallback: None,
    };
    node.prepare(&gpu.device, &gpu.queue, &inputs)
        .expect("a proper transform passes");
    SceneDescription::from_json(&scene_with_matrix(good), Path::new("."))
        .expect("and loads from a scene file");
}

/// 65504 is the largest finite f16; anything above uploads as infinity (and the light then
/// contributes 0), so it is an error naming the texel. Negative and non-finite texels are too.
#[test]
fn texel_above_f16_range_is_rejected() {
    let texels = |v: f32| {
        let mut t = vec![Vec3::splat(0.5); 4];
        t[3] = Vec3::new(0.0, v, 0.0);
        t
    };
    LightTexture::new(2, 2, texels(65504.0)).expect("the f16 maximum is fine");
    for v in [65505.0, 65520.0, 1e6, f32::MAX] {
        let got = LightTexture::new(2, 2, texels(v));
        assert!(
            matches!(got, Err(Error::TexelOutOfRange { texel: 3, value }) if value == v),
            "{v}: {got:?}"
        );
    }
    for v in [-1.0, f32::NAN, f32::INFINITY] {
        let got = LightTexture::new(2, 2, texels(v));
        assert!(
            matches!(got, Err(Error::Negative { .. } | Error::NonFinite { .. })),
            "{v}: {got:?}"
        );
    }
    // A checkerboard colour above the range, too.
    let got = LightTexture::checkerboard(4, 2, Vec3::ONE, Vec3::splat(1e5));
    assert!(matches!(got, Err(Error::TexelOutOfRange { .. })), "{got:?}");
}
