//! Scene files: the standard scenes load, values round-trip, every error names its field, no
//! input panics, and `ray_distance` agrees with analytic geometry.

use std::path::{Path, PathBuf};

use volshadow::glam::{DVec3, Mat4, Vec3};
use volshadow::nodes::{Scale, UpsampleFilter};
use volshadow::scene_file::{Method, SceneDescription};
use volshadow::{Error, Light, PhaseFunction, SceneFileError, SpotLight};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

fn scene_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(scenes_dir())
        .expect("scenes/ exists")
        .map(|e| e.expect("readable entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    files.sort();
    files
}

fn parse(text: &str) -> volshadow::Result<SceneDescription> {
    SceneDescription::from_json(text, Path::new("."))
}

/// A minimal valid scene with `insert` spliced in as extra top-level members (which replace the
/// defaults of the same name, as serde_json keeps the last duplicate key).
const BASE: &str = r#"{
  "name": "base",
  "camera": { "eye": [0, 2, 8], "target": [0, 1, 0], "fov_y_degrees": 45, "near": 0.1 },
  "lights": [ { "type": "point", "position": [0, 6, 0], "intensity": 10 } ],
  "medium": { "sigma_s": 0.05 }
  INSERT
}"#;

fn with(insert: &str) -> String {
    let extra = if insert.is_empty() {
        String::new()
    } else {
        format!(", {insert}")
    };
    BASE.replace("INSERT", &extra)
}

/// Parses `text`, expects an error, checks it is a `SceneFile` error whose field is `field` and
/// whose message contains `field` and every string of `contains`.
fn expect_error(text: &str, field: &str, contains: &[&str]) -> String {
    let err = parse(text).expect_err("the scene must be rejected");
    let message = err.to_string();
    match &err {
        Error::SceneFile(SceneFileError { path, field: f, .. }) => {
            assert_eq!(path, "<string>", "{message}");
            assert_eq!(f, field, "{message}");
        }
        other => panic!("expected Error::SceneFile, got {other:?}"),
    }
    assert!(message.contains(field), "{message:?} does not name {field}");
    for c in contains {
        assert!(message.contains(c), "{message:?} does not contain {c:?}");
    }
    message
}

#[test]
fn base_scene_is_valid() {
    let scene = parse(&with("")).unwrap();
    assert_eq!(scene.size, (512, 512));
    assert_eq!(scene.method, Method::default());
    assert!(scene.objects.is_empty());
}

#[test]
fn every_standard_scene_loads() {
    let files = scene_files();
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    for expected in [
        "sphere",
        "cow",
        "spring",
        "fence",
        "stained_glass",
        "stiff_fog",
        "window",
        "soft",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "scenes/{expected}.json missing"
        );
    }
    for file in &files {
        let scene = SceneDescription::load(file)
            .unwrap_or_else(|e| panic!("{} does not load: {e}", file.display()));
        assert_eq!(scene.size, (512, 512), "{}", file.display());
        assert!(!scene.lights.is_empty());
        assert!(scene.description.is_some(), "{}", file.display());
        // A ground receiver at y = 0 that casts no shadow, and at least one occluder.
        let ground = scene
            .objects
            .iter()
            .find(|o| o.name == "ground")
            .unwrap_or_else(|| panic!("{}: no ground", file.display()));
        assert!(!ground.casts_shadow);
        let (lo, hi) = ground.mesh.bounds();
        assert_eq!((lo.y, hi.y), (0.0, 0.0));
        assert!(
            !scene.reference_occluders().is_empty(),
            "{}",
            file.display()
        );
        // The camera sees the ground straight down from the eye.
        let eye = scene.camera.eye().as_dvec3();
        let d = scene.ray_distance(eye, DVec3::NEG_Y);
        assert!(d.is_finite() && d > 0.0, "{}: {d}", file.display());
    }
}

#[test]
fn scene_specifics() {
    let load =
        |name: &str| SceneDescription::load(scenes_dir().join(format!("{name}.json"))).unwrap();
    let sphere = load("sphere");
    assert_eq!(
        sphere.medium.phase(),
        PhaseFunction::HenyeyGreenstein { g: 0.6 }
    );
    assert_eq!(sphere.method, Method::default(), "no method: the default");
    let cow = load("cow");
    assert!(
        cow.objects.len() >= 10,
        "ground, body, head, snout, 4 legs, 2 horns"
    );
    let glass = load("stained_glass");
    assert!(matches!(glass.lights[0].light, Light::Spot(_)));
    let texture = glass.lights[0].texture.as_ref().expect("textured spot");
    assert_eq!((texture.width(), texture.height()), (256, 256));
    // Several distinct saturated colours and dark lead.
    let t = texture.texels();
    assert!(t.iter().any(|c| c.max_element() < 0.05));
    let saturated = t
        .iter()
        .filter(|c| c.max_element() > 0.2 && c.min_element() < 0.5 * c.max_element())
        .count();
    assert!(saturated > t.len() / 2, "{saturated} of {}", t.len());
    let fence = load("fence");
    let posts = fence.objects.iter().find(|o| o.name == "fence").unwrap();
    assert_eq!(posts.mesh.triangle_count(), (12 + 2) * 12);
    assert!(posts.mesh.is_closed());
}

#[test]
fn stiff_fog_optical_depth() {
    let scene = SceneDescription::load(scenes_dir().join("stiff_fog.json")).unwrap();
    let d = scene
        .camera
        .eye()
        .distance(scene.lights[0].light.position().unwrap());
    let sigma_t = scene.medium.sigma_t();
    for c in 0..3 {
        let tau = sigma_t[c] * d;
        assert!((40.0..=60.0).contains(&tau), "sigma_t * D = {tau}");
    }
    assert!(scene.name.contains("50"), "{}", scene.name);
}

#[test]
fn round_trip_values() {
    let text = r#"{
      "name": "round trip",
      "description": "values",
      "size": [320, 200],
      "camera": { "eye": [1, 2, 3], "target": [0, 1, 0], "up": [0, 2, 0],
                  "fov_y_degrees": 60, "near": 0.5, "far": 100, "reversed_z": true },
      "lights": [
        { "type": "point", "position": [0, 5, 1], "intensity": [10, 20, 30] },
        { "type": "spot", "position": [0, 6, 0], "direction": [0, -2, 0],
          "cone_angle_degrees": 90, "intensity": 7,
          "texture": { "checkerboard": { "size": 8, "cells": 2, "a": 1, "b": [0, 0.5, 0] } } }
      ],
      "medium": { "sigma_s": [0.1, 0.2, 0.3], "sigma_a": 0.05, "phase": "mie_hazy" },
      "objects": [
        { "name": "a", "shape": { "type": "box", "center": [0, 1, 0], "half_extents": [1, 2, 3] },
          "transform": { "translate": [1, 2, 3], "rotate_degrees": [0, 90, 0], "scale": 2 } },
        { "shape": { "type": "cylinder", "center": [0, 0, 0], "radius": 1, "half_height": 2 },
          "transform": { "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 5,6,7,1] },
          "casts_shadow": false, "albedo": [0.1, 0.2, 0.3] },
        { "shape": { "type": "torus", "center": [0, 0, 0], "major_radius": 2, "minor_radius": 0.5 } },
        { "shape": { "type": "spring", "center": [0, 0, 0], "coil_radius": 1, "wire_radius": 0.1,
                     "turns": 2.5, "height": 2 } },
        { "shape": { "type": "fence", "posts": 3, "spacing": 1, "post_half_extents": [0.1, 1, 0.1] } }
      ],
      "method": { "type": "brute_force", "steps": 32, "bisections": 2, "scale": 4 }
    }"#;
    let s = parse(text).unwrap();
    assert_eq!(s.name, "round trip");
    assert_eq!(s.description.as_deref(), Some("values"));
    assert_eq!(s.size, (320, 200));
    assert!((s.camera.eye() - Vec3::new(1.0, 2.0, 3.0)).length() < 1e-5);
    assert_eq!(s.camera.far_depth(), 0.0, "reversed Z");
    // Aspect ratio 320 / 200 and the vertical field of view.
    let p = s.camera.projection();
    assert!((p.y_axis.y - 1.0 / 30f32.to_radians().tan()).abs() < 1e-5);
    assert!((p.y_axis.y / p.x_axis.x - 1.6).abs() < 1e-5);

    assert_eq!(s.lights.len(), 2);
    assert_eq!(s.lights[0].light.position(), Some(Vec3::new(0.0, 5.0, 1.0)));
    assert_eq!(s.lights[0].light.intensity(), Vec3::new(10.0, 20.0, 30.0));
    assert!(s.lights[0].texture.is_none());
    match s.lights[1].light {
        Light::Spot(spot) => {
            assert_eq!(spot.direction(), Vec3::NEG_Y);
            assert!((spot.cone_angle() - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
            assert_eq!(spot.intensity(), Vec3::splat(7.0));
        }
        other => panic!("expected a spot light, got {other:?}"),
    }
    let tex = s.lights[1].texture.as_ref().unwrap();
    assert_eq!((tex.width(), tex.height()), (8, 8));
    assert_eq!(tex.texels()[0], Vec3::ONE);
    assert_eq!(tex.texels()[4], Vec3::new(0.0, 0.5, 0.0));

    assert_eq!(s.medium.sigma_s(), Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(s.medium.sigma_a(), Vec3::splat(0.05));
    assert_eq!(s.medium.phase(), PhaseFunction::MieHazy);

    assert_eq!(s.objects.len(), 5);
    let a = &s.objects[0];
    assert_eq!(a.name, "a");
    assert!(a.casts_shadow);
    assert_eq!(a.albedo, Vec3::splat(0.8));
    // The box's own centre is in the mesh; the transform is T · R · S.
    let (lo, hi) = a.mesh.bounds();
    assert_eq!(
        (lo, hi),
        (Vec3::new(-1.0, -1.0, -3.0), Vec3::new(1.0, 3.0, 3.0))
    );
    let expected = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0))
        * Mat4::from_rotation_y(90f32.to_radians())
        * Mat4::from_scale(Vec3::splat(2.0));
    assert!(a.transform.abs_diff_eq(expected, 1e-6), "{}", a.transform);
    let x = a.transform.transform_point3(Vec3::X);
    assert!((x - Vec3::new(1.0, 2.0, 1.0)).length() < 1e-5, "{x}");

    let b = &s.objects[1];
    assert_eq!(b.name, "cylinder_1");
    assert!(!b.casts_shadow);
    assert_eq!(b.albedo, Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(
        b.transform,
        Mat4::from_translation(Vec3::new(5.0, 6.0, 7.0))
    );
    assert_eq!(s.objects[2].name, "torus_2");
    assert!(s.objects[2].mesh.is_closed());
    assert!(s.objects[3].mesh.is_closed());
    assert_eq!(s.objects[4].mesh.triangle_count(), 36);
    assert_eq!(s.reference_occluders().len(), 4);

    assert_eq!(
        s.method,
        Method::BruteForce {
            steps: 32,
            bisections: 2,
            scale: Scale::Quarter
        }
    );
    let settings = s.method.march_settings().unwrap();
    assert_eq!((settings.steps, settings.bisections), (32, 2));
}

#[test]
fn methods_and_phases() {
    let m = |json: &str| {
        parse(&with(&format!(r#""method": {json}"#)))
            .unwrap()
            .method
    };
    assert_eq!(m(r#""reference""#), Method::Reference);
    assert_eq!(m(r#""hybrid""#), Method::hybrid_default());
    assert_eq!(m(r#""exact""#), Method::default());
    assert_eq!(
        m(
            r#"{"type": "hybrid", "scale": 2, "upsample": {"separable": {"taps": 5, "sigma_spatial": 1, "sigma_depth": 0.1}}}"#
        ),
        Method::Hybrid {
            steps: 64,
            scale: Scale::Half,
            upsample: UpsampleFilter::Separable {
                taps: 5,
                sigma_spatial: 1.0,
                sigma_depth: 0.1
            },
            bisections: 0,
            texture_steps: 32
        }
    );
    let medium = |json: &str| {
        parse(
            &BASE
                .replace(
                    r#""medium": { "sigma_s": 0.05 }"#,
                    &format!(r#""medium": {json}"#),
                )
                .replace("INSERT", ""),
        )
        .unwrap()
        .medium
    };
    let hp = medium(
        r#"{"phase": {"hoffman_preetham": {"rayleigh": [0.01, 0.02, 0.04], "mie": 0.03, "g": 0.7}}}"#,
    );
    assert!(hp.sigma_s().abs_diff_eq(Vec3::new(0.04, 0.05, 0.07), 1e-7));
    assert!(matches!(hp.phase(), PhaseFunction::HoffmanPreetham { g, .. } if g == 0.7));
    assert_eq!(
        medium(r#"{"sigma_s": 0.1, "phase": "rayleigh"}"#).phase(),
        PhaseFunction::Rayleigh
    );
    assert_eq!(
        medium(r#"{"sigma_s": 0.1}"#).phase(),
        PhaseFunction::Isotropic
    );
    assert_eq!(medium(r#"{"sigma_s": 0.1}"#).sigma_a(), Vec3::ZERO);
}

#[test]
fn error_syntax() {
    let text = "{\n  \"name\": \"x\",\n  \"size\": [1, 2,\n}";
    let message = expect_error(text, "(json)", &["line 4", "column"]);
    assert!(message.starts_with("<string>: (json): "), "{message}");
}

#[test]
fn error_unknown_field() {
    expect_error(&with(r#""colour": 1"#), "colour", &["unknown field"]);
    let text = with(r#""objects": [{"shape": {"type": "sphere", "center": [0,1,0], "radus": 1}}]"#);
    expect_error(
        &text,
        "objects[0].shape.radus",
        &["unknown field", "radius"],
    );
    let text = BASE
        .replace("\"near\": 0.1", "\"near\": 0.1, \"fov\": 3")
        .replace("INSERT", "");
    expect_error(&text, "camera.fov", &["unknown field"]);
}

#[test]
fn error_missing_field() {
    let text = BASE.replace(r#""name": "base","#, "").replace("INSERT", "");
    expect_error(&text, "name", &["missing"]);
    let text = with(r#""objects": [{"shape": {"type": "sphere", "center": [0,1,0]}}]"#);
    expect_error(&text, "objects[0].shape.radius", &["missing"]);
    let text = with(
        r#""lights": [{"type": "point", "position": [0,1,0], "intensity": 1}, {"position": [0,1,0]}]"#,
    );
    expect_error(&text, "lights[1].type", &["missing", "point", "spot"]);
}

#[test]
fn error_wrong_type() {
    let text =
        with(r#""objects": [{"shape": {"type": "sphere", "center": [0,1,0], "radius": "big"}}]"#);
    expect_error(
        &text,
        "objects[0].shape.radius",
        &["expected a number", "string"],
    );
    let text = with(r#""size": [512, "512"]"#);
    expect_error(&text, "size[1]", &["integer"]);
    let text = with(r#""size": [512.5, 512]"#);
    expect_error(&text, "size[0]", &["integer"]);
    let text = BASE.replace("[0, 2, 8]", "[0, 2]").replace("INSERT", "");
    expect_error(&text, "camera.eye", &["3 numbers", "2 elements"]);
    let text = with(r#""objects": [{"shape": {"type": "cube", "center": [0,1,0]}}]"#);
    expect_error(
        &text,
        "objects[0].shape.type",
        &["unknown shape type", "box"],
    );
    let text = with(
        r#""objects": [{"shape": {"type": "box", "center": [0,1,0], "half_extents": [1,1,1]}, "casts_shadow": "yes"}]"#,
    );
    expect_error(&text, "objects[0].casts_shadow", &["true or false"]);
}

#[test]
fn error_negative_sigma() {
    let text = BASE
        .replace(r#""sigma_s": 0.05"#, r#""sigma_s": [0.1, -0.2, 0.1]"#)
        .replace("INSERT", "");
    expect_error(&text, "medium.sigma_s", &["must be >= 0"]);
    let text = BASE
        .replace(r#""sigma_s": 0.05"#, r#""sigma_s": 0.05, "sigma_a": -1"#)
        .replace("INSERT", "");
    expect_error(&text, "medium.sigma_a", &["must be >= 0"]);
    let text = BASE
        .replace(r#""sigma_s": 0.05"#, r#""sigma_s": 0.05, "phase": {"hoffman_preetham": {"rayleigh": 0.1, "mie": 0.1, "g": 0.5}}"#)
        .replace("INSERT", "");
    expect_error(&text, "medium.sigma_s", &["hoffman_preetham"]);
}

#[test]
fn error_bad_cone_angle() {
    let text = with(
        r#""lights": [{"type": "point", "position": [0,1,0], "intensity": 1},
                      {"type": "spot", "position": [0,5,0], "direction": [0,-1,0], "cone_angle_degrees": 200, "intensity": 1}]"#,
    );
    let message = expect_error(&text, "lights[1].cone_angle_degrees", &["(0, 179]", "200"]);
    assert_eq!(
        message,
        "<string>: lights[1].cone_angle_degrees: must be in (0, 179] (the widest field a spot's \
         shadow map covers), got 200"
    );
    // The widest cone loads (179°, `SpotLight::MAX_CONE_ANGLE`); just above it does not.
    let at = |degrees: &str| {
        with(&format!(
            r#""lights": [{{"type": "spot", "position": [0,5,0], "direction": [0,-1,0], "cone_angle_degrees": {degrees}, "intensity": 1}}]"#
        ))
    };
    let scene = parse(&at("179")).unwrap();
    match scene.lights[0].light {
        Light::Spot(s) => assert_eq!(s.cone_angle(), SpotLight::MAX_CONE_ANGLE),
        other => panic!("{other:?}"),
    }
    expect_error(
        &at("179.001"),
        "lights[0].cone_angle_degrees",
        &["(0, 179]"],
    );
}

/// A spot's `texture_up` is its texture frame's up hint (`SpotLight::with_texture_up`),
/// none when left out; one along the direction, zero or of the wrong length is an error
/// naming it.
#[test]
fn spot_texture_up() {
    let at = |up: &str| {
        with(&format!(
            r#""lights": [{{"type": "spot", "position": [0,5,0], "direction": [0,-1,0], "cone_angle_degrees": 40, "intensity": 1{up}}}]"#
        ))
    };
    let spot = |text: &str| match parse(text).unwrap().lights[0].light {
        Light::Spot(s) => s,
        other => panic!("{other:?}"),
    };
    assert_eq!(spot(&at("")).texture_up(), None);
    let turned = spot(&at(r#", "texture_up": [0, 0, 2]"#));
    assert_eq!(turned.texture_up(), Some(volshadow::glam::Vec3::Z));
    for bad in ["[0, -3, 0]", "[0, 0, 0]"] {
        let message = expect_error(
            &at(&format!(r#", "texture_up": {bad}"#)),
            "lights[0].texture_up",
            &["a part across the direction"],
        );
        assert!(
            message.starts_with("<string>: lights[0].texture_up: "),
            "{message}"
        );
    }
    parse(&at(r#", "texture_up": [1, 0]"#)).unwrap_err();
}

/// A light's `radius` is read (soft shadows), defaults to 0, and a negative one is an error
/// naming it (was: an unknown field).
#[test]
fn light_radius() {
    let text = with(
        r#""lights": [{"type": "point", "position": [0,1,0], "intensity": 1, "radius": 0.25},
                      {"type": "spot", "position": [0,5,0], "direction": [0,-1,0], "cone_angle_degrees": 40, "intensity": 1, "radius": 0.5},
                      {"type": "point", "position": [0,2,0], "intensity": 1}]"#,
    );
    let s = parse(&text).unwrap();
    let radii: Vec<f32> = s.lights.iter().map(|l| l.light.radius()).collect();
    assert_eq!(radii, [0.25, 0.5, 0.0]);
    let text = with(
        r#""lights": [{"type": "spot", "position": [0,5,0], "direction": [0,-1,0], "cone_angle_degrees": 40, "intensity": 1, "radius": -1}]"#,
    );
    let message = expect_error(&text, "lights[0].radius", &["-1"]);
    assert_eq!(
        message,
        "<string>: lights[0].radius: must be finite and at least 0, got -1"
    );
}

#[test]
fn error_asymmetry_out_of_range() {
    for g in ["1", "-1", "1.5"] {
        let text = BASE
            .replace(
                r#""sigma_s": 0.05"#,
                &format!(r#""sigma_s": 0.05, "phase": {{"henyey_greenstein": {g}}}"#),
            )
            .replace("INSERT", "");
        expect_error(&text, "medium.phase.henyey_greenstein", &["(-1, 1)"]);
    }
    let text = BASE
        .replace(
            r#""sigma_s": 0.05"#,
            r#""phase": {"hoffman_preetham": {"rayleigh": 0.1, "mie": 0.1, "g": -1}}"#,
        )
        .replace("INSERT", "");
    expect_error(&text, "medium.phase.hoffman_preetham.g", &["(-1, 1)"]);
}

#[test]
fn error_zero_size() {
    expect_error(
        &with(r#""size": [0, 512]"#),
        "size[0]",
        &["1..=8192", "got 0"],
    );
    expect_error(&with(r#""size": [512, 9000]"#), "size[1]", &["1..=8192"]);
}

#[test]
fn error_bad_scale() {
    let text = with(r#""method": {"type": "hybrid", "scale": 3}"#);
    expect_error(&text, "method.scale", &["1, 2 or 4", "got 3"]);
    let text = with(
        r#""objects": [{"shape": {"type": "box", "center": [0,1,0], "half_extents": [1,1,1]}, "transform": {"scale": [1, 0, 1]}}]"#,
    );
    expect_error(&text, "objects[0].transform.scale", &["must be in"]);
}

#[test]
fn error_zero_taps() {
    let text = with(
        r#""method": {"type": "hybrid", "scale": 2, "upsample": {"separable": {"taps": 0, "sigma_spatial": 1, "sigma_depth": 0.1}}}"#,
    );
    expect_error(&text, "method.upsample.separable.taps", &["odd", "got 0"]);
}

#[test]
fn error_other_validation() {
    let object = |shape: &str| with(&format!(r#""objects": [{{"shape": {shape}}}]"#));
    expect_error(
        &object(r#"{"type": "torus", "center": [0,0,0], "major_radius": 1, "minor_radius": 2}"#),
        "objects[0].shape.minor_radius",
        &["major_radius"],
    );
    expect_error(
        &object(r#"{"type": "sphere", "center": [0,0,0], "radius": 1, "segments": 2}"#),
        "objects[0].shape.segments",
        &["3..=1024"],
    );
    expect_error(
        &object(r#"{"type": "sphere", "center": [0,0,0], "radius": 1e-300}"#),
        "objects[0].shape.radius",
        &["must be in"],
    );
    expect_error(
        &object(r#"{"type": "plane", "center": [0,1e9,0], "half_size": [1, 1]}"#),
        "objects[0].shape.center",
        &["within"],
    );
    let gltf = object(r#"{"type": "gltf", "path": "missing.glb"}"#);
    let message = parse(&gltf).unwrap_err().to_string();
    assert!(message.contains("objects[0].shape"), "{message}");
    if cfg!(not(feature = "gltf")) {
        assert!(
            message.contains("built without the `gltf` feature"),
            "{message}"
        );
    }
    let file_texture = with(
        r#""lights": [{"type": "spot", "position": [0,5,0], "direction": [0,-1,0], "cone_angle_degrees": 40, "intensity": 1, "texture": {"file": "missing.png"}}]"#,
    );
    let message = parse(&file_texture).unwrap_err().to_string();
    assert!(message.contains("lights[0].texture.file"), "{message}");
    if cfg!(not(feature = "image")) {
        assert!(message.contains("`image` feature"), "{message}");
    }
    expect_error(
        &BASE
            .replace("[0, 1, 0], \"fov", "[0, 2, 8], \"fov")
            .replace("INSERT", ""),
        "camera.target",
        &["eye"],
    );
    expect_error(
        &BASE
            .replace(
                "\"near\": 0.1",
                "\"near\": 0.1, \"up\": [0, 0, -1], \"far\": 0.05",
            )
            .replace("INSERT", ""),
        "camera.far",
        &["near"],
    );
    expect_error(&with(r#""lights": []"#), "lights", &["at least one"]);
    expect_error(
        &with(r#""lights": [{"type": "point", "position": [0,1,0], "intensity": 0}]"#),
        "lights[0].intensity",
        &["zero"],
    );
    expect_error(
        &with(
            r#""objects": [{"shape": {"type": "box", "center": [0,1,0], "half_extents": [1,1,1]}, "transform": {"matrix": [1,0,0,0, 0,1,0,0, 0,0,-1,0, 0,0,0,1]}}]"#,
        ),
        "objects[0].transform",
        &["determinant"],
    );
    expect_error(
        &with(
            r#""objects": [{"shape": {"type": "box", "center": [0,1,0], "half_extents": [1,1,1]}, "transform": {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1], "scale": 2}}]"#,
        ),
        "objects[0].transform.scale",
        &["matrix"],
    );
    let missing = SceneDescription::load(scenes_dir().join("no_such_scene.json")).unwrap_err();
    assert!(
        matches!(&missing, Error::SceneFile(SceneFileError { field, .. }) if field == "(file)"),
        "{missing}"
    );
}

/// Every prefix of every standard scene is an error, never a panic.
#[test]
fn truncated_files_error_without_panicking() {
    for file in scene_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        let text = text.trim_end();
        for end in 0..text.len() {
            if !text.is_char_boundary(end) {
                continue;
            }
            let result = SceneDescription::from_json(&text[..end], &scenes_dir());
            assert!(
                result.is_err(),
                "{} truncated at {end} was accepted",
                file.display()
            );
        }
    }
}

/// Every number of every standard scene replaced by awkward values: never a panic.
#[test]
fn mutated_numbers_never_panic() {
    let replacements = [
        "-1", "0", "1e39", "-1e300", "0.5", "3", "1e-40", "\"x\"", "null", "[]", "{}",
    ];
    for file in scene_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        let bytes = text.as_bytes();
        let mut numbers = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            let c = bytes[i];
            let starts = (c == b'-' || c.is_ascii_digit())
                && i > 0
                && matches!(bytes[i - 1], b' ' | b'[' | b':' | b',');
            if starts {
                let end = (i + 1..bytes.len())
                    .find(|&j| !matches!(bytes[j], b'0'..=b'9' | b'.' | b'e' | b'E' | b'-' | b'+'))
                    .unwrap_or(bytes.len());
                numbers.push((i, end));
                i = end;
            } else {
                i += 1;
            }
        }
        assert!(numbers.len() > 10, "{}", file.display());
        for &(start, end) in &numbers {
            for r in replacements {
                let mutated = format!("{}{}{}", &text[..start], r, &text[end..]);
                let _ = SceneDescription::from_json(&mutated, &scenes_dir());
            }
        }
    }
}

fn one_object(shape: &str, transform: &str) -> SceneDescription {
    parse(&with(&format!(
        r#""objects": [{{"shape": {shape}, "transform": {transform}}}]"#
    )))
    .unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs()
}

#[test]
fn ray_distance_plane() {
    // A 4 × 6 plane at height 1.5 (translated), rotated by 90° about Y (so it spans 6 in X).
    let scene = one_object(
        r#"{"type": "plane", "center": [0, 0.5, 0], "half_size": [2, 3]}"#,
        r#"{"translate": [0, 1, 0], "rotate_degrees": [0, 90, 0]}"#,
    );
    let plane_y = 1.5f64;
    for (origin, dir) in [
        (DVec3::new(0.0, 10.0, 0.0), DVec3::new(0.0, -1.0, 0.0)),
        (DVec3::new(0.3, 4.0, -0.7), DVec3::new(0.5, -2.0, 0.25)),
        (DVec3::new(-2.5, -3.0, 1.0), DVec3::new(0.1, 1.0, -0.1)),
        (DVec3::new(1.0, 1.6, 1.0), DVec3::new(0.3, -0.1, 0.0)),
    ] {
        let u = dir.normalize();
        let expected = (plane_y - origin.y) / u.y;
        let hit = origin + u * expected;
        assert!(
            hit.x.abs() < 3.0 && hit.z.abs() < 2.0,
            "test ray must hit: {hit}"
        );
        let got = scene.ray_distance(origin, dir);
        assert!(close(got, expected), "{origin} {dir}: {got} vs {expected}");
    }
    // Outside the rotated extent (|z| < 2), parallel, pointing away, zero direction.
    assert_eq!(
        scene.ray_distance(DVec3::new(0.0, 5.0, 2.5), DVec3::NEG_Y),
        f64::INFINITY
    );
    assert_eq!(
        scene.ray_distance(DVec3::new(0.0, 5.0, 0.0), DVec3::X),
        f64::INFINITY
    );
    assert_eq!(
        scene.ray_distance(DVec3::new(0.0, 5.0, 0.0), DVec3::Y),
        f64::INFINITY
    );
    assert_eq!(
        scene.ray_distance(DVec3::new(0.0, 5.0, 0.0), DVec3::ZERO),
        f64::INFINITY
    );
}

#[test]
fn ray_distance_sphere() {
    // Unit sphere mesh scaled by 2 and moved to (1, 3, -2): its poles are vertices exactly on
    // the analytic sphere of radius 2, so rays aimed at them hit it at the analytic distance.
    let scene = one_object(
        r#"{"type": "sphere", "center": [0, 0, 0], "radius": 1, "segments": 8, "rings": 4}"#,
        r#"{"translate": [1, 3, -2], "scale": 2}"#,
    );
    let center = DVec3::new(1.0, 3.0, -2.0);
    let r = 2.0f64;
    for (origin, target) in [
        (center + DVec3::new(0.0, 10.0, 0.0), center + DVec3::Y * r),
        (center + DVec3::new(0.3, 7.0, 0.2), center + DVec3::Y * r),
        (center + DVec3::new(-1.5, 4.0, 2.5), center + DVec3::Y * r),
        (center + DVec3::new(0.3, -7.0, 0.2), center - DVec3::Y * r),
        (center + DVec3::new(2.0, -5.0, -1.0), center - DVec3::Y * r),
    ] {
        let expected = (target - origin).length();
        let got = scene.ray_distance(origin, target - origin);
        assert!(
            close(got, expected),
            "{origin} → {target}: {got} vs {expected}"
        );
    }
    // Bounds: a ray through the middle hits the mesh between the inscribed and circumscribed
    // spheres; rays passing outside the analytic sphere miss.
    let origin = center + DVec3::new(0.0, 0.0, 10.0);
    let d = scene.ray_distance(origin, DVec3::NEG_Z);
    assert!((8.0 - 1e-6..=8.5).contains(&d), "{d}");
    assert_eq!(
        scene.ray_distance(center + DVec3::new(2.1, 0.0, 10.0), DVec3::NEG_Z),
        f64::INFINITY
    );
    // From inside: the far side.
    let inside = scene.ray_distance(center, DVec3::Y);
    assert!(close(inside, r), "{inside}");
    // The nearest of two objects.
    let two = parse(&with(
        r#""objects": [
            {"shape": {"type": "plane", "center": [0, 0, 0], "half_size": [10, 10]}, "casts_shadow": false},
            {"shape": {"type": "box", "center": [0, 1, 0], "half_extents": [0.5, 0.25, 0.5]}}
        ]"#,
    ))
    .unwrap();
    assert!(close(
        two.ray_distance(DVec3::new(0.1, 5.0, 0.2), DVec3::NEG_Y),
        3.75
    ));
    assert!(close(
        two.ray_distance(DVec3::new(3.0, 5.0, 0.2), DVec3::NEG_Y),
        5.0
    ));
    assert_eq!(two.reference_occluders().len(), 1);
}

/// A glTF object: its meshes become objects with the node transform composed after the
/// object's, loaded relative to the scene file.
#[cfg(feature = "gltf")]
#[test]
fn gltf_object() {
    fn base64(bytes: &[u8]) -> String {
        const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for chunk in bytes.chunks(3) {
            let b = [
                chunk[0],
                *chunk.get(1).unwrap_or(&0),
                *chunk.get(2).unwrap_or(&0),
            ];
            let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
            for k in 0..4 {
                if k <= chunk.len() {
                    out.push(ALPHABET[((n >> (18 - 6 * k)) & 63) as usize] as char);
                } else {
                    out.push('=');
                }
            }
        }
        out
    }
    let positions: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let bytes: Vec<u8> = positions.iter().flat_map(|p| p.to_le_bytes()).collect();
    let gltf = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
            "nodes": [{{"mesh": 0, "translation": [0, 2, 0]}}],
            "meshes": [{{"name": "tri", "primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
            "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                            "min": [0, 0, 0], "max": [1, 0, 1]}}],
            "bufferViews": [{{"buffer": 0, "byteLength": 36}}],
            "buffers": [{{"byteLength": 36, "uri": "data:application/octet-stream;base64,{}"}}]}}"#,
        base64(&bytes)
    );
    let dir = std::env::temp_dir().join(format!("volshadow-scene-file-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("models")).unwrap();
    std::fs::write(dir.join("models/tri.gltf"), gltf).unwrap();
    let scene_path = dir.join("scene.json");
    std::fs::write(
        &scene_path,
        with(
            r#""objects": [{"name": "model", "shape": {"type": "gltf", "path": "models/tri.gltf"},
                             "transform": {"translate": [1, 0, 0]}, "casts_shadow": true}]"#,
        ),
    )
    .unwrap();
    let scene = SceneDescription::load(&scene_path);
    std::fs::remove_dir_all(&dir).ok();
    let scene = scene.unwrap();
    assert_eq!(scene.objects.len(), 1);
    let o = &scene.objects[0];
    assert_eq!(o.name, "model/tri");
    assert_eq!(
        o.transform,
        Mat4::from_translation(Vec3::new(1.0, 2.0, 0.0))
    );
    assert!(close(
        scene.ray_distance(DVec3::new(1.2, 5.0, 0.2), DVec3::NEG_Y),
        3.0
    ));
    assert_eq!(scene.reference_occluders().len(), 1);
}

/// A light texture from a PNG file next to the scene file (feature `image`).
#[cfg(feature = "image")]
#[test]
fn texture_file() {
    let dir = std::env::temp_dir().join(format!("volshadow-scene-texture-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png =
        image::RgbImage::from_fn(4, 2, |x, _| image::Rgb([if x < 2 { 255 } else { 0 }, 0, 0]));
    png.save(dir.join("glass.png")).unwrap();
    let scene_path = dir.join("scene.json");
    std::fs::write(
        &scene_path,
        with(r#""lights": [{"type": "spot", "position": [0, 5, 0], "direction": [0, -1, 0],
                            "cone_angle_degrees": 40, "intensity": 1, "texture": {"file": "glass.png"}}]"#),
    )
    .unwrap();
    let scene = SceneDescription::load(&scene_path);
    std::fs::remove_dir_all(&dir).ok();
    let scene = scene.unwrap();
    let texture = scene.lights[0].texture.as_ref().unwrap();
    assert_eq!((texture.width(), texture.height()), (4, 2));
    assert_eq!(texture.texels()[0], Vec3::X);
    assert_eq!(texture.texels()[3], Vec3::ZERO);
}
