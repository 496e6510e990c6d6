//! Textured spot lights against the f64 reference (issue 4): a coloured checkerboard and a
//! texture of thin lines projected through fog past a sphere occluder, the march crossing the
//! texture's flat regions in one step each; and the map of those regions against its
//! definition.

use volshadow::nodes::{Encode, Node};

use glam::{DVec3, Mat4, Vec3};
use volshadow::gpu::{Occluder, OccluderMesh};
use volshadow::nodes::{LightTextureInput, LightTextureNode, MarchSettings};
use volshadow::reference::{self, TexturedSpot, TriangleMesh};
use volshadow::scene::{shapes, LightTexture, TextureChannels};
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

/// The medium of most of this file's tests: HG 0.5, σs (0.2, 0.22, 0.25), σa 0.03.
fn hg_medium() -> Medium {
    Medium::new(
        Vec3::new(0.2, 0.22, 0.25),
        Vec3::splat(0.03),
        PhaseFunction::HenyeyGreenstein { g: 0.5 },
    )
    .unwrap()
}

/// `mesh` as the reference's occluder, where it stands.
fn reference_occluder(mesh: &volshadow::scene::Mesh) -> [reference::Occluder; 1] {
    [reference::Occluder::Mesh(TriangleMesh::from_indexed(
        mesh.positions(),
        mesh.indices(),
        glam::DMat4::IDENTITY,
    ))]
}

/// The reference's `SIZE`² in-scatter of `spot` projecting `texture` over the ground.
fn textured_reference(
    camera: &volshadow::Camera,
    medium: &Medium,
    spot: SpotLight,
    texture: &LightTexture,
    occluders: &[reference::Occluder],
) -> Vec<glam::DVec3> {
    let textured = TexturedSpot { spot, texture };
    reference::inscatter_image(camera, SIZE, SIZE, ground, medium, &textured, occluders)
}

/// The scene of this file: a spot above a sphere (centre 0, 2.2, 0; radius 0.5) over a
/// ground, a coloured checkerboard, and the camera looking at the sphere.
struct Rig {
    spot: SpotLight,
    texture: LightTexture,
    camera: volshadow::Camera,
    center: Vec3,
    /// The march's settings (default: `MarchSettings::default()`).
    march: MarchSettings,
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
        camera: volshadow_harness::look_at(
            Vec3::new(0.0, 1.6, 5.5),
            Vec3::new(0.0, 1.5, 0.0),
            60.0,
            1.0,
        ),
        center: Vec3::new(0.0, 2.2, 0.0),
        march: MarchSettings::default(),
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
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let depths = volshadow_harness::depths_at(&rig.camera, size, size, ground);
    let depth = volshadow_harness::depth_texture(&gpu, size, size, &depths);
    let gpu_mesh = OccluderMesh::new(&gpu.device, mesh);
    let occluders = [Occluder {
        mesh: &gpu_mesh,
        transform: Mat4::IDENTITY,
    }];
    let uploaded = rig.texture.upload(&gpu.device, &gpu.queue);
    let passes =
        volshadow_harness::ShadowPasses::new(&rig.camera, light, medium, &depth, &occluders)
            .settings(rig.march)
            .texture(Some(&uploaded));
    volshadow_harness::shadow_frame(&gpu, &cache, &passes).inscatter
}

/// RMSE of the GPU in-scatter against the reference, relative to the reference's mean.
fn textured_rmse(medium: &Medium) -> f64 {
    textured_rmse_of(rig(), medium)
}

/// [`textured_rmse`] for `rig`.
fn textured_rmse_of(rig: Rig, medium: &Medium) -> f64 {
    let Rig {
        spot,
        ref texture,
        camera,
        center,
        ..
    } = rig;
    let mesh = shapes::uv_sphere(center, 0.5, 24, 12).unwrap();
    let inscatter = textured_inscatter(&rig, &Light::from(spot), medium, &mesh, SIZE);
    assert!(inscatter
        .iter()
        .all(|t| t[0..3].iter().all(|v| v.is_finite() && *v >= 0.0)));

    let textured = TexturedSpot { spot, texture };
    let ref_occ = reference_occluder(&mesh);
    let rgb = |v: &[glam::DVec3]| -> Vec<[f64; 3]> { v.iter().map(|r| r.to_array()).collect() };
    let reference = rgb(&reference::inscatter_image(
        &camera, SIZE, SIZE, ground, medium, &textured, &ref_occ,
    ));
    let image: Vec<[f64; 3]> = inscatter
        .iter()
        .map(|g| [0, 1, 2].map(|c| f64::from(g[c])))
        .collect();
    // The texture matters: a uniform white texture gives a clearly different image.
    let plain = rgb(&reference::inscatter_image(
        &camera, SIZE, SIZE, ground, medium, &spot, &ref_occ,
    ));
    let plain_rmse = relative_rmse(&plain, &reference);
    assert!(
        plain_rmse > 0.1,
        "the texture should change the image, RMSE without it {plain_rmse:.3}"
    );
    relative_rmse(&image, &reference)
}

#[test]
fn checkerboard_spot_matches_reference() {
    let medium = hg_medium();
    let rmse = textured_rmse(&medium);
    println!("textured spot, HG 0.5: RMSE {rmse:.4} of mean");
    volshadow_harness::metric::accuracy(
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
    volshadow_harness::metric::accuracy(
        "checkerboard textured spot, Hoffman–Preetham",
        format!("RMSE {:.2}%", 100.0 * rmse),
        format!("RMSE {}%", 100.0 * MAX_RMSE),
    );
    assert!(rmse <= MAX_RMSE, "RMSE {rmse:.4}");
}

/// A texture of 1-texel lines and dots on a flat ground (`size`², lines about every 11 texels
/// each way, one dot in about 60 texels), deterministic in `seed`.
fn thin_lines(size: u32, seed: u64) -> LightTexture {
    let mut rng = volshadow_harness::rng::Rng::new(seed);
    let lines = |rng: &mut volshadow_harness::rng::Rng| {
        let mut at = vec![false; size as usize];
        let mut i = rng.range(2.0, 11.0) as usize;
        while i < size as usize {
            at[i] = true;
            i += rng.range(5.0, 17.0) as usize;
        }
        at
    };
    let (rows, cols) = (lines(&mut rng), lines(&mut rng));
    let (ground, line, dot) = (
        Vec3::new(0.9, 0.8, 0.7),
        Vec3::splat(0.02),
        Vec3::new(0.1, 0.6, 0.1),
    );
    let texels = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as usize, (i / size) as usize);
            if rows[y] || cols[x] {
                line
            } else if rng.next() < 1.0 / 60.0 {
                dot
            } else {
                ground
            }
        })
        .collect();
    LightTexture::new(size, size, texels).unwrap()
}

/// The march crosses a flat region of the texture in one step, so it must not step over a
/// line or a dot one texel wide between two of them: a 96² texture of such lines and dots on
/// a flat ground (a fifth of its texels) against the reference, RMSE within the textured
/// spot's bar (3%). The ground alone (no lines, no dots) is far from this reference (RMSE
/// 202% of its mean, most of it from the few pixels whose rays pass by the light, about 300
/// times the mean). Measured RMSE 0.72%; with each flat square one cell wider than its map
/// says (the line or dot at its edge stepped over), 17.1%: it fails.
#[test]
fn thin_lines_between_flat_regions_match_the_reference() {
    let medium = hg_medium();
    let texture = thin_lines(96, 17);
    let lines = texture.texels().iter().filter(|t| t.x < 0.5).count();
    assert!(
        lines * 8 > texture.texels().len(),
        "lines and dots: {lines} texels"
    );
    let rmse = textured_rmse_of(
        Rig {
            texture: texture.clone(),
            ..rig()
        },
        &medium,
    );
    // The ground alone against the lines' reference.
    let rig = rig();
    let flat_ground = LightTexture::new(96, 96, vec![Vec3::new(0.9, 0.8, 0.7); 96 * 96]).unwrap();
    let mesh = shapes::uv_sphere(rig.center, 0.5, 24, 12).unwrap();
    let ref_occ = reference_occluder(&mesh);
    let image = |t: &LightTexture| textured_reference(&rig.camera, &medium, rig.spot, t, &ref_occ);
    let (with, without) = (image(&texture), image(&flat_ground));
    let (mut sq, mut sum) = (0.0, 0.0);
    for (a, b) in with.iter().zip(&without) {
        for c in 0..3 {
            sq += (a[c] - b[c]).powi(2);
            sum += a[c];
        }
    }
    let n = 3.0 * with.len() as f64;
    let ground_rmse = (sq / n).sqrt() / (sum / n);
    println!("thin lines: RMSE {rmse:.4} of mean; the ground alone {ground_rmse:.4}");
    volshadow_harness::metric::accuracy(
        "textured spot, 1-texel lines and dots between flat regions",
        format!(
            "RMSE {:.2}% (the ground alone {:.1}%)",
            100.0 * rmse,
            100.0 * ground_rmse
        ),
        format!("RMSE {}%", 100.0 * MAX_RMSE),
    );
    assert!(
        ground_rmse > 2.0 * MAX_RMSE,
        "the lines matter: {ground_rmse}"
    );
    assert!(rmse <= MAX_RMSE, "RMSE {rmse:.4}");
}

/// A piece whose image crosses more regions of the texture than `texture_steps` is traced that
/// far and marched in uniform steps to its end: the thin lines' scene with `texture_steps` 4
/// (most pieces go beyond) puts into the view the light the full trace does (`texture_steps`
/// 4096), total within 5%: the uniform steps read coarser mips, which average the same texels,
/// so the total stays where the image's detail does not. Measured 0.85%; with the rest of the
/// piece dropped, 82.6%.
#[test]
fn a_piece_beyond_texture_steps_is_marched_to_its_end() {
    let medium = hg_medium();
    let mesh = shapes::uv_sphere(Vec3::new(0.0, 2.2, 0.0), 0.5, 24, 12).unwrap();
    let total = |texture_steps: u32| {
        let rig = Rig {
            texture: thin_lines(96, 17),
            march: MarchSettings {
                texture_steps,
                ..MarchSettings::default()
            },
            ..rig()
        };
        let image = textured_inscatter(&rig, &Light::from(rig.spot), &medium, &mesh, SIZE);
        assert!(image
            .iter()
            .all(|t| t[0..3].iter().all(|v| v.is_finite() && *v >= 0.0)));
        image
            .iter()
            .map(|t| f64::from(t[0] + t[1] + t[2]))
            .sum::<f64>()
    };
    let (few, all) = (total(4), total(4096));
    let difference = (few - all).abs() / all;
    println!("texture_steps 4: total {few:.4}; 4096: {all:.4}; difference {difference:.4}");
    assert!(
        difference <= 0.05,
        "texture_steps 4 against 4096: {difference:.4}"
    );
}

/// The light texture's map of flat regions, computed here from its definition
/// ([`LightTextureNode`]'s docs) on the texels as uploaded (f16): per cell between four texel
/// centres (clamped at the edges; flat when the four are equal) and per quadrant (+x+y, −x+y,
/// +x−y, −x−y), the side of the largest square of flat cells of the map, at most 63, with the
/// cell at its corner extending into that quadrant; 0 where the cell is not flat.
fn flats_of(texture: &LightTexture) -> Vec<u8> {
    let (w, h) = (i64::from(texture.width()), i64::from(texture.height()));
    let texel = |x: i64, y: i64| {
        let t = texture.texels()[(y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize];
        t.to_array().map(|v| half::f16::from_f32(v).to_bits())
    };
    let (cw, ch) = ((w - 1).max(1), (h - 1).max(1));
    let flat = |x: i64, y: i64| {
        let a = texel(x, y);
        (0..cw).contains(&x)
            && (0..ch).contains(&y)
            && texel(x + 1, y) == a
            && texel(x, y + 1) == a
            && texel(x + 1, y + 1) == a
    };
    // Grown from side k to k + 1 by the cells of its new row and column.
    let square = |x: i64, y: i64, sx: i64, sy: i64| {
        let mut k = 0;
        while k < 63
            && (0..=k).all(|i| flat(x + k * sx, y + i * sy) && flat(x + i * sx, y + k * sy))
        {
            k += 1;
        }
        k as u8
    };
    (0..ch)
        .flat_map(|y| (0..cw).map(move |x| (x, y)))
        .flat_map(|(x, y)| {
            [(1, 1), (-1, 1), (1, -1), (-1, -1)].map(|(sx, sy)| square(x, y, sx, sy))
        })
        .collect()
}

/// The map the node builds equals its definition ([`flats_of`]) on textures with flat
/// regions of every size, lines and dots one texel wide, flat regions wider than the map's
/// largest square, and the degenerate sizes (1×1, a row, a column). Any change to the map's
/// rule fails: with a square's growth stopped one row late (its last row's run may be one
/// short), 7 of the 9 textures differ.
#[test]
fn the_flat_region_map_is_its_definition() {
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let c = |v: f32| Vec3::new(v, 1.0 - v, 0.5);
    let mut dot = vec![c(0.25); 120 * 100];
    dot[40 * 120 + 90] = c(0.75);
    let textures = [
        (
            "stained glass 64², 4 panes",
            volshadow::scene_file::stained_glass(64, 4, 7).unwrap(),
        ),
        (
            "checkerboard 40², 5 cells",
            LightTexture::checkerboard(40, 5, c(0.0), c(1.0)).unwrap(),
        ),
        ("thin lines 96²", thin_lines(96, 17)),
        (
            "one dot in 120 × 100",
            LightTexture::new(120, 100, dot).unwrap(),
        ),
        ("1 × 1", LightTexture::new(1, 1, vec![c(0.5)]).unwrap()),
        (
            "7 × 1",
            LightTexture::new(7, 1, [0.0, 0.0, 0.0, 1.0, 1.0, 0.5, 0.5].map(c).to_vec()).unwrap(),
        ),
        (
            "1 × 5",
            LightTexture::new(1, 5, [1.0, 1.0, 0.0, 0.0, 0.0].map(c).to_vec()).unwrap(),
        ),
        (
            "2 × 2 flat",
            LightTexture::new(2, 2, vec![c(0.125); 4]).unwrap(),
        ),
        (
            "3 × 3, the centre apart",
            LightTexture::new(
                3,
                3,
                (0..9).map(|i| c(if i == 4 { 1.0 } else { 0.0 })).collect(),
            )
            .unwrap(),
        ),
    ];
    let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let mut node = LightTextureNode::new(&gpu.device, &cache).unwrap();
    let mut wrong = Vec::new();
    for (name, texture) in &textures {
        let uploaded = texture.upload(&gpu.device, &gpu.queue);
        let input = LightTextureInput {
            texture: &uploaded,
            channels: TextureChannels::Rgb,
        };
        assert!(node.prepare(&gpu.device, &gpu.queue, &input).unwrap());
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        node.encode(&mut encoder, None).unwrap();
        gpu.submit_and_wait(encoder).unwrap();
        let map = gpu.read_texture_bytes(node.flats().unwrap()).unwrap();
        let expected = flats_of(texture);
        let differ = map.iter().zip(&expected).filter(|(a, b)| a != b).count();
        let flat = expected.chunks(4).filter(|m| m[0] > 0).count();
        let widest = expected.iter().max().copied().unwrap_or(0);
        println!(
            "{name}: {} cells, {flat} flat, largest square {widest}, {differ} of {} sides differ",
            expected.len() / 4,
            expected.len()
        );
        if map.len() != expected.len() || differ > 0 {
            wrong.push(*name);
        }
    }
    assert!(pollster::block_on(scope.pop()).is_none());
    assert!(wrong.is_empty(), "maps unlike their definition: {wrong:?}");
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
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let scope = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let mut node = LightTextureNode::new(&gpu.device, &cache).unwrap();
    for format in [
        wgpu::TextureFormat::R32Uint,
        wgpu::TextureFormat::Rgba32Float,
    ] {
        let t = volshadow_harness::texture(
            &gpu,
            format,
            wgpu::TextureUsages::TEXTURE_BINDING,
            (4, 4, 1),
            1,
        );
        let input = LightTextureInput {
            texture: &t,
            channels: TextureChannels::Red,
        };
        let err = node.prepare(&gpu.device, &gpu.queue, &input).err();
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
    let medium = hg_medium();
    let rig = rig();
    let Rig {
        spot,
        ref texture,
        camera,
        center,
        ..
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
    let soft = volshadow_harness::scene::errors(
        &render(&light),
        &reference,
        &camera,
        &light,
        (SOFT_SIZE, SOFT_SIZE),
    );
    let hard_light = Light::from(spot.with_radius(0.0).unwrap());
    let hard = volshadow_harness::scene::errors(
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
    let hard_own = volshadow_harness::scene::errors(
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
    volshadow_harness::metric::accuracy(
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

/// RMSE of `a` against `b` (RGB), relative to `b`'s mean.
fn relative_rmse(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let (mut sq, mut sum) = (0.0, 0.0);
    for (a, b) in a.iter().zip(b) {
        for c in 0..3 {
            sq += (a[c] - b[c]).powi(2);
            sum += b[c];
        }
    }
    let n = 3.0 * a.len() as f64;
    (sq / n).sqrt() / (sum / n)
}

/// A spot's texture frame turns with its up hint ([`SpotLight::with_texture_up`]) and
/// [`TextureChannels::Red`] takes the red channel alone as a grey mask (the convention of
/// engines' light masks, Bevy's `SpotLightTexture`): a 16² texture whose red, green and blue
/// are three unrelated random patterns of 4×4-texel blocks, projected by the rig's spot with
/// an up hint 90° from the frame it would pick, in a medium of HG 0.5, against the reference
/// with the red texels as grey and the same frame. Bar: the textured spot's 3% RMSE
/// (`MAX_RMSE`). The test tells the two mistakes it guards apart: the same reference with the
/// spot's default frame, and with the texture's own RGB, are each more than 20% (RMSE,
/// relative to the mean; most of it near the light) from it (measured 450.6% and 259.6%).
/// Measured RMSE 0.67% (lavapipe, 2026-12-04). Broken variants, run: the GPU reading the
/// texture's RGB, 259.5%; `texture_frame` ignoring the hint, 450.6%: both fail.
#[test]
fn a_red_mask_turned_by_the_spots_up_hint_matches_the_reference() {
    let medium = hg_medium();
    let size = 16u32;
    let mut rng = volshadow_harness::rng::Rng::new(7);
    let mut blocks = || -> Vec<f32> { (0..16).map(|_| rng.range(0.05, 1.0) as f32).collect() };
    let (red, green, blue) = (blocks(), blocks(), blocks());
    let at = |b: &[f32], i: u32| b[((i / size / 4) * 4 + (i % size) / 4) as usize];
    let colour = (0..size * size)
        .map(|i| Vec3::new(at(&red, i), at(&green, i), at(&blue, i)))
        .collect();
    let colour = LightTexture::new(size, size, colour).unwrap();
    let grey = (0..size * size).map(|i| Vec3::splat(at(&red, i))).collect();
    let grey = LightTexture::new(size, size, grey).unwrap();

    let mut rig = rig();
    // The frame the spot picks for itself has +x along the hint X's part across the axis;
    // this hint is 90° from it about the axis.
    let default_up = rig.spot.texture_frame().inverse().y_axis.truncate();
    let hint = rig.spot.direction().cross(default_up);
    let plain_spot = rig.spot;
    rig.spot = rig.spot.with_texture_up(hint).unwrap();
    rig.texture = colour.clone();
    let mesh = shapes::uv_sphere(rig.center, 0.5, 24, 12).unwrap();
    let gpu = volshadow_harness::gpu();
    let cache = volshadow_harness::cache(&gpu);
    let depths = volshadow_harness::depths_at(&rig.camera, SIZE, SIZE, ground);
    let depth = volshadow_harness::depth_texture(&gpu, SIZE, SIZE, &depths);
    let gpu_mesh = OccluderMesh::new(&gpu.device, &mesh);
    let occluders = [Occluder {
        mesh: &gpu_mesh,
        transform: Mat4::IDENTITY,
    }];
    let uploaded = colour.upload(&gpu.device, &gpu.queue);
    let light = Light::from(rig.spot);
    let passes =
        volshadow_harness::ShadowPasses::new(&rig.camera, &light, &medium, &depth, &occluders)
            .texture(Some(&uploaded))
            .channels(TextureChannels::Red);
    let image: Vec<[f64; 3]> = volshadow_harness::shadow_frame(&gpu, &cache, &passes)
        .inscatter
        .iter()
        .map(|t| [0, 1, 2].map(|c| f64::from(t[c])))
        .collect();
    assert!(image.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));

    let ref_occ = reference_occluder(&mesh);
    let reference_of = |spot: SpotLight, texture: &LightTexture| -> Vec<[f64; 3]> {
        textured_reference(&rig.camera, &medium, spot, texture, &ref_occ)
            .iter()
            .map(|r| r.to_array())
            .collect()
    };
    let truth = reference_of(rig.spot, &grey);
    let unturned = relative_rmse(&reference_of(plain_spot, &grey), &truth);
    let coloured = relative_rmse(&reference_of(rig.spot, &colour), &truth);
    let rmse = relative_rmse(&image, &truth);
    println!(
        "red mask, turned frame: RMSE {:.2}% (default frame {:.1}%, RGB {:.1}%)",
        100.0 * rmse,
        100.0 * unturned,
        100.0 * coloured
    );
    volshadow_harness::metric::accuracy(
        "red-mask textured spot, turned frame",
        format!("RMSE {:.2}%", 100.0 * rmse),
        format!("RMSE {}%", 100.0 * MAX_RMSE),
    );
    assert!(
        unturned > 0.2 && coloured > 0.2,
        "the frame and the channels must change the image: {unturned:.3}, {coloured:.3}"
    );
    assert!(rmse <= MAX_RMSE, "RMSE {rmse:.4}");
}
