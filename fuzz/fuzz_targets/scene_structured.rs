//! The scene-file parser on JSON documents shaped like scene files: an `Arbitrary` value that
//! mirrors the schema (every section, light, texture, shape, transform and method, with
//! numbers drawn towards the edges of their ranges), sometimes with a field of the wrong type
//! or an unknown key, serialised to JSON text.
#![no_main]

mod common;

use std::sync::OnceLock;

use arbitrary::Arbitrary;
use libfuzzer_sys::fuzz_target;
use serde_json::{json, Map, Value};
use volshadow::scene_file::SceneDescription;

/// A number: small integers, edges of the documented ranges, or any finite f64.
#[derive(Arbitrary, Debug)]
enum Num {
    Int(i16),
    Edge(u8),
    Any(f64),
}

const EDGES: [f64; 24] = [
    0.0, -0.0, 1.0, -1.0, 2.0, 3.0, 0.5, 1e-6, 9e-7, 1e-4, 1e6, 1.1e6, 1e9, 179.999, 180.0, 1024.0,
    1025.0, 4096.0, 8192.0, 8193.0, 16384.0, 65504.0, 65505.0, 1e308,
];

impl Num {
    fn value(&self) -> Value {
        match *self {
            Num::Int(i) => json!(i),
            Num::Edge(k) => json!(EDGES[k as usize % EDGES.len()]),
            // JSON has no NaN or infinity: serde_json writes them as null.
            Num::Any(x) => json!(x),
        }
    }
}

#[derive(Arbitrary, Debug)]
enum Vec3 {
    Three(Num, Num, Num),
    One(Num),
    Wrong(Vec<Num>),
}

impl Vec3 {
    fn value(&self) -> Value {
        match self {
            Vec3::Three(a, b, c) => json!([a.value(), b.value(), c.value()]),
            Vec3::One(a) => a.value(),
            Vec3::Wrong(v) => Value::Array(v.iter().map(Num::value).collect()),
        }
    }
}

/// Any JSON value, for fields of the wrong type.
#[derive(Arbitrary, Debug)]
enum Junk {
    Null,
    Bool(bool),
    Num(Num),
    Str(String),
    Arr(Vec<Num>),
    Obj(Vec<(String, Num)>),
}

impl Junk {
    fn value(&self) -> Value {
        match self {
            Junk::Null => Value::Null,
            Junk::Bool(b) => json!(b),
            Junk::Num(n) => n.value(),
            Junk::Str(s) => json!(s),
            Junk::Arr(v) => Value::Array(v.iter().map(Num::value).collect()),
            Junk::Obj(v) => Value::Object(v.iter().map(|(k, n)| (k.clone(), n.value())).collect()),
        }
    }
}

/// A field: present with its own type, absent, or replaced by junk.
#[derive(Arbitrary, Debug)]
enum F<T> {
    Some(T),
    Absent,
    Junk(Junk),
}

trait ToValue {
    fn value(&self) -> Value;
}
impl ToValue for Num {
    fn value(&self) -> Value {
        Num::value(self)
    }
}
impl ToValue for Vec3 {
    fn value(&self) -> Value {
        Vec3::value(self)
    }
}
impl ToValue for bool {
    fn value(&self) -> Value {
        json!(self)
    }
}
impl ToValue for String {
    fn value(&self) -> Value {
        json!(self)
    }
}

/// An object from its fields (absent ones left out), plus maybe an unknown key.
fn object(fields: Vec<(&str, Option<Value>)>, extra: &Option<(String, Junk)>) -> Value {
    let mut map = Map::new();
    for (k, v) in fields {
        if let Some(v) = v {
            map.insert(k.to_owned(), v);
        }
    }
    if let Some((k, v)) = extra {
        map.insert(k.clone(), v.value());
    }
    Value::Object(map)
}

fn field<T: ToValue>(f: &F<T>) -> Option<Value> {
    match f {
        F::Some(t) => Some(t.value()),
        F::Absent => None,
        F::Junk(j) => Some(j.value()),
    }
}

#[derive(Arbitrary, Debug)]
struct Camera {
    eye: F<Vec3>,
    target: F<Vec3>,
    up: F<Vec3>,
    fov: F<Num>,
    near: F<Num>,
    far: F<Num>,
    reversed: F<bool>,
}

#[derive(Arbitrary, Debug)]
enum Texture {
    Checkerboard {
        size: F<Num>,
        cells: F<Num>,
        a: F<Vec3>,
        b: F<Vec3>,
    },
    StainedGlass {
        size: F<Num>,
        cells: F<Num>,
        seed: F<Num>,
    },
    File(F<String>),
}

#[derive(Arbitrary, Debug)]
enum Light {
    Point {
        position: F<Vec3>,
        intensity: F<Vec3>,
    },
    Spot {
        position: F<Vec3>,
        direction: F<Vec3>,
        cone: F<Num>,
        intensity: F<Vec3>,
        texture: Option<Texture>,
    },
}

#[derive(Arbitrary, Debug)]
enum Phase {
    Named(u8),
    Hg(F<Num>),
    Hp {
        rayleigh: F<Vec3>,
        mie: F<Vec3>,
        g: F<Num>,
    },
}

#[derive(Arbitrary, Debug)]
struct Medium {
    sigma_s: F<Vec3>,
    sigma_a: F<Vec3>,
    phase: Option<Phase>,
}

#[derive(Arbitrary, Debug)]
enum Shape {
    Sphere {
        center: F<Vec3>,
        radius: F<Num>,
        segments: F<Num>,
        rings: F<Num>,
    },
    Box {
        center: F<Vec3>,
        half: F<Vec3>,
    },
    Plane {
        center: F<Vec3>,
        half: (F<Num>, F<Num>),
    },
    Torus {
        center: F<Vec3>,
        major: F<Num>,
        minor: F<Num>,
        m: F<Num>,
        n: F<Num>,
    },
    Spring {
        center: F<Vec3>,
        coil: F<Num>,
        wire: F<Num>,
        turns: F<Num>,
        height: F<Num>,
        per_turn: F<Num>,
        wire_segments: F<Num>,
    },
    Cylinder {
        center: F<Vec3>,
        radius: F<Num>,
        half_height: F<Num>,
        segments: F<Num>,
    },
    Fence {
        center: F<Vec3>,
        posts: F<Num>,
        spacing: F<Num>,
        half: F<Vec3>,
        rail: F<bool>,
    },
    Gltf(F<String>),
}

#[derive(Arbitrary, Debug)]
enum Transform {
    Trs {
        translate: F<Vec3>,
        rotate: F<Vec3>,
        scale: F<Vec3>,
    },
    Matrix(Vec<Num>),
}

#[derive(Arbitrary, Debug)]
struct Object {
    name: F<String>,
    shape: Shape,
    transform: Option<Transform>,
    casts_shadow: F<bool>,
    albedo: F<Vec3>,
}

#[derive(Arbitrary, Debug)]
enum Method {
    Named(u8),
    Object {
        kind: u8,
        steps: F<Num>,
        bisections: F<Num>,
        scale: F<Num>,
        texture_steps: F<Num>,
        upsample: Option<Upsample>,
    },
}

#[derive(Arbitrary, Debug)]
enum Upsample {
    Named(u8),
    Separable {
        taps: F<Num>,
        sigma_spatial: F<Num>,
        sigma_depth: F<Num>,
    },
}

#[derive(Arbitrary, Debug)]
struct Scene {
    name: F<String>,
    description: F<String>,
    size: Option<(F<Num>, F<Num>)>,
    camera: F<Camera>,
    lights: Vec<Light>,
    medium: F<Medium>,
    objects: Option<Vec<Object>>,
    method: Option<Method>,
    extra: Option<(String, Junk)>,
}

impl ToValue for Camera {
    fn value(&self) -> Value {
        object(
            vec![
                ("eye", field(&self.eye)),
                ("target", field(&self.target)),
                ("up", field(&self.up)),
                ("fov_y_degrees", field(&self.fov)),
                ("near", field(&self.near)),
                ("far", field(&self.far)),
                ("reversed_z", field(&self.reversed)),
            ],
            &None,
        )
    }
}

fn pick(names: &[&str], k: u8) -> Value {
    json!(names[k as usize % names.len()])
}

impl ToValue for Texture {
    fn value(&self) -> Value {
        match self {
            Texture::Checkerboard { size, cells, a, b } => json!({"checkerboard": object(vec![
                ("size", field(size)), ("cells", field(cells)), ("a", field(a)), ("b", field(b))], &None)}),
            Texture::StainedGlass { size, cells, seed } => json!({"stained_glass": object(vec![
                ("size", field(size)), ("cells", field(cells)), ("seed", field(seed))], &None)}),
            Texture::File(f) => object(vec![("file", field(f))], &None),
        }
    }
}

impl ToValue for Light {
    fn value(&self) -> Value {
        match self {
            Light::Point {
                position,
                intensity,
            } => object(
                vec![
                    ("type", Some(json!("point"))),
                    ("position", field(position)),
                    ("intensity", field(intensity)),
                ],
                &None,
            ),
            Light::Spot {
                position,
                direction,
                cone,
                intensity,
                texture,
            } => object(
                vec![
                    ("type", Some(json!("spot"))),
                    ("position", field(position)),
                    ("direction", field(direction)),
                    ("cone_angle_degrees", field(cone)),
                    ("intensity", field(intensity)),
                    ("texture", texture.as_ref().map(ToValue::value)),
                ],
                &None,
            ),
        }
    }
}

impl ToValue for Medium {
    fn value(&self) -> Value {
        let phase = self.phase.as_ref().map(|p| match p {
            Phase::Named(k) => pick(
                &["isotropic", "rayleigh", "mie_hazy", "mie_murky", "other"],
                *k,
            ),
            Phase::Hg(g) => json!({"henyey_greenstein": field(g)}),
            Phase::Hp { rayleigh, mie, g } => json!({"hoffman_preetham": object(vec![
                ("rayleigh", field(rayleigh)), ("mie", field(mie)), ("g", field(g))], &None)}),
        });
        object(
            vec![
                ("sigma_s", field(&self.sigma_s)),
                ("sigma_a", field(&self.sigma_a)),
                ("phase", phase),
            ],
            &None,
        )
    }
}

impl ToValue for Shape {
    fn value(&self) -> Value {
        let t = |s: &str| Some(json!(s));
        match self {
            Shape::Sphere {
                center,
                radius,
                segments,
                rings,
            } => object(
                vec![
                    ("type", t("sphere")),
                    ("center", field(center)),
                    ("radius", field(radius)),
                    ("segments", field(segments)),
                    ("rings", field(rings)),
                ],
                &None,
            ),
            Shape::Box { center, half } => object(
                vec![
                    ("type", t("box")),
                    ("center", field(center)),
                    ("half_extents", field(half)),
                ],
                &None,
            ),
            Shape::Plane { center, half } => object(
                vec![
                    ("type", t("plane")),
                    ("center", field(center)),
                    ("half_size", Some(json!([field(&half.0), field(&half.1)]))),
                ],
                &None,
            ),
            Shape::Torus {
                center,
                major,
                minor,
                m,
                n,
            } => object(
                vec![
                    ("type", t("torus")),
                    ("center", field(center)),
                    ("major_radius", field(major)),
                    ("minor_radius", field(minor)),
                    ("major_segments", field(m)),
                    ("minor_segments", field(n)),
                ],
                &None,
            ),
            Shape::Spring {
                center,
                coil,
                wire,
                turns,
                height,
                per_turn,
                wire_segments,
            } => object(
                vec![
                    ("type", t("spring")),
                    ("center", field(center)),
                    ("coil_radius", field(coil)),
                    ("wire_radius", field(wire)),
                    ("turns", field(turns)),
                    ("height", field(height)),
                    ("segments_per_turn", field(per_turn)),
                    ("wire_segments", field(wire_segments)),
                ],
                &None,
            ),
            Shape::Cylinder {
                center,
                radius,
                half_height,
                segments,
            } => object(
                vec![
                    ("type", t("cylinder")),
                    ("center", field(center)),
                    ("radius", field(radius)),
                    ("half_height", field(half_height)),
                    ("segments", field(segments)),
                ],
                &None,
            ),
            Shape::Fence {
                center,
                posts,
                spacing,
                half,
                rail,
            } => object(
                vec![
                    ("type", t("fence")),
                    ("center", field(center)),
                    ("posts", field(posts)),
                    ("spacing", field(spacing)),
                    ("post_half_extents", field(half)),
                    ("rail", field(rail)),
                ],
                &None,
            ),
            Shape::Gltf(path) => object(vec![("type", t("gltf")), ("path", field(path))], &None),
        }
    }
}

impl ToValue for Transform {
    fn value(&self) -> Value {
        match self {
            Transform::Trs {
                translate,
                rotate,
                scale,
            } => object(
                vec![
                    ("translate", field(translate)),
                    ("rotate_degrees", field(rotate)),
                    ("scale", field(scale)),
                ],
                &None,
            ),
            Transform::Matrix(m) => json!({"matrix": m.iter().map(Num::value).collect::<Vec<_>>()}),
        }
    }
}

impl ToValue for Object {
    fn value(&self) -> Value {
        object(
            vec![
                ("name", field(&self.name)),
                ("shape", Some(self.shape.value())),
                ("transform", self.transform.as_ref().map(ToValue::value)),
                ("casts_shadow", field(&self.casts_shadow)),
                ("albedo", field(&self.albedo)),
            ],
            &None,
        )
    }
}

impl ToValue for Method {
    fn value(&self) -> Value {
        const KINDS: [&str; 4] = ["reference", "hybrid", "brute_force", "other"];
        match self {
            Method::Named(k) => pick(&KINDS, *k),
            Method::Object {
                kind,
                steps,
                bisections,
                scale,
                texture_steps,
                upsample,
            } => object(
                vec![
                    ("type", Some(pick(&KINDS, *kind))),
                    ("steps", field(steps)),
                    ("bisections", field(bisections)),
                    ("scale", field(scale)),
                    ("texture_steps", field(texture_steps)),
                    (
                        "upsample",
                        upsample.as_ref().map(|u| match u {
                            Upsample::Named(k) => {
                                pick(&["bilinear", "depth_aware_3x3", "other"], *k)
                            }
                            Upsample::Separable {
                                taps,
                                sigma_spatial,
                                sigma_depth,
                            } => json!({"separable": object(vec![
                        ("taps", field(taps)), ("sigma_spatial", field(sigma_spatial)),
                        ("sigma_depth", field(sigma_depth))], &None)}),
                        }),
                    ),
                ],
                &None,
            ),
        }
    }
}

impl ToValue for Scene {
    fn value(&self) -> Value {
        object(
            vec![
                ("name", field(&self.name)),
                ("description", field(&self.description)),
                (
                    "size",
                    self.size.as_ref().map(|(w, h)| json!([field(w), field(h)])),
                ),
                ("camera", field(&self.camera)),
                (
                    "lights",
                    Some(Value::Array(
                        self.lights.iter().map(ToValue::value).collect(),
                    )),
                ),
                ("medium", field(&self.medium)),
                (
                    "objects",
                    self.objects
                        .as_ref()
                        .map(|o| Value::Array(o.iter().map(ToValue::value).collect())),
                ),
                ("method", self.method.as_ref().map(ToValue::value)),
            ],
            &self.extra,
        )
    }
}

static FOLDER: OnceLock<std::path::PathBuf> = OnceLock::new();

fuzz_target!(|scene: Scene| {
    let folder = FOLDER.get_or_init(common::empty_folder);
    let text = scene.value().to_string();
    let _ = SceneDescription::from_json_with(&text, folder, &common::options());
});
