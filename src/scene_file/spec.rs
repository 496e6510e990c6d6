//! The structure of a scene file as serde types. `deny_unknown_fields` everywhere, `null`
//! counts as absent (every optional field is an `Option`), and every error carries the path of
//! its field: `serde_path_to_error` tracks it, and [`Tagged`] keeps tracking it inside the
//! enums tagged by `"type"`. Ranges and cross-field rules are checked when the scene is built.

use std::fmt;

use serde::de::{self, DeserializeOwned, Deserializer, IgnoredAny, SeqAccess, Visitor};
use serde::Deserialize;
use serde_json::{Map, Value};

/// A finite number within the range of `f32`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Num(pub f32);

/// A non-negative integer (a JSON integer, or a float with no fraction).
#[derive(Debug, Clone, Copy)]
pub(super) struct Int(pub u64);

/// A [`Int`] that fits in `u32`.
#[derive(Debug, Clone, Copy)]
pub(super) struct U32(pub u32);

/// `true` or `false`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Flag(pub bool);

/// Exactly `N` numbers.
#[derive(Debug, Clone, Copy)]
pub(super) struct Floats<const N: usize>(pub [f32; N]);

/// A colour, coefficient or scale: `[r, g, b]` or one number for all three channels.
#[derive(Debug, Clone, Copy)]
pub(super) struct Rgb(pub glam::Vec3);

/// Visits one number as `f64`.
struct Scalar(&'static str);

impl Visitor<'_> for Scalar {
    type Value = f64;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(self.0)
    }
    fn visit_f64<E: de::Error>(self, x: f64) -> Result<f64, E> {
        Ok(x)
    }
    fn visit_u64<E: de::Error>(self, x: u64) -> Result<f64, E> {
        Ok(x as f64)
    }
    fn visit_i64<E: de::Error>(self, x: i64) -> Result<f64, E> {
        Ok(x as f64)
    }
}

/// `x` as `f32`, or an error if it is beyond its range.
fn to_f32<E: de::Error>(x: f64) -> Result<f32, E> {
    if x.abs() > f64::from(f32::MAX) {
        return Err(E::custom(format!("{x} is out of range for a 32-bit float")));
    }
    Ok(x as f32)
}

/// Exactly `N` numbers of a sequence (the rest are counted for the message).
fn exactly<'de, A: SeqAccess<'de>, const N: usize>(mut seq: A) -> Result<[f32; N], A::Error> {
    let mut out = [0.0; N];
    let mut n = 0;
    while n < N {
        match seq.next_element::<Num>()? {
            Some(Num(x)) => out[n] = x,
            None => break,
        }
        n += 1;
    }
    while seq.next_element::<IgnoredAny>()?.is_some() {
        n += 1;
    }
    if n != N {
        return Err(de::Error::custom(format!(
            "expected an array of {N} numbers, got {n} elements"
        )));
    }
    Ok(out)
}

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        to_f32(d.deserialize_any(Scalar("a number"))?).map(Num)
    }
}

impl<'de> Deserialize<'de> for Int {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = u64;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a non-negative integer")
            }
            fn visit_u64<E: de::Error>(self, n: u64) -> Result<u64, E> {
                Ok(n)
            }
            fn visit_i64<E: de::Error>(self, n: i64) -> Result<u64, E> {
                self.visit_f64(n as f64)
            }
            // Integers are exact up to 2^53 as floats too.
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<u64, E> {
                if x >= 0.0 && x.fract() == 0.0 && x <= 9_007_199_254_740_992.0 {
                    return Ok(x as u64);
                }
                Err(E::custom(format!(
                    "expected a non-negative integer, got {x}"
                )))
            }
        }
        d.deserialize_any(V).map(Int)
    }
}

impl<'de> Deserialize<'de> for U32 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let Int(n) = Int::deserialize(d)?;
        u32::try_from(n)
            .map(U32)
            .map_err(|_| de::Error::custom(format!("{n} is out of range (at most {})", u32::MAX)))
    }
}

impl<'de> Deserialize<'de> for Flag {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = bool;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("true or false")
            }
            fn visit_bool<E: de::Error>(self, b: bool) -> Result<bool, E> {
                Ok(b)
            }
        }
        d.deserialize_bool(V).map(Flag)
    }
}

impl<'de, const N: usize> Deserialize<'de> for Floats<N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<const N: usize>;
        impl<'de, const N: usize> Visitor<'de> for V<N> {
            type Value = [f32; N];
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of {N} numbers")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Value, A::Error> {
                exactly(seq)
            }
        }
        d.deserialize_seq(V::<N>).map(Floats)
    }
}

impl<'de> Deserialize<'de> for Rgb {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = glam::Vec3;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E: de::Error>(self, x: f64) -> Result<Self::Value, E> {
                to_f32(x).map(glam::Vec3::splat)
            }
            fn visit_u64<E: de::Error>(self, x: u64) -> Result<Self::Value, E> {
                self.visit_f64(x as f64)
            }
            fn visit_i64<E: de::Error>(self, x: i64) -> Result<Self::Value, E> {
                self.visit_f64(x as f64)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Self::Value, A::Error> {
                exactly(seq).map(glam::Vec3::from_array)
            }
        }
        d.deserialize_any(V).map(Rgb)
    }
}

/// Marks a message that carries the path inside a [`Tagged`] value: `MARK path MARK message`.
pub(super) const MARK: char = '\u{1}';

/// An enum tagged by a `"type"` key, for [`Tagged`].
pub(super) trait Kind: DeserializeOwned {
    /// What it is, for messages (`"shape"`).
    const KIND: &'static str;
    /// The tags, in the order messages list them.
    const TYPES: &'static [&'static str];
    /// Whether a bare string names a type with its defaults (`"method": "hybrid"`).
    const NAMED: bool = false;
}

/// An internally tagged enum (`{"type": "sphere", ...}`) read as the externally tagged
/// `{"sphere": {...}}`, so that errors inside it keep their field path (serde's own
/// `#[serde(tag)]` buffers the value and loses it).
#[derive(Debug)]
pub(super) struct Tagged<T>(pub T);

impl<'de, T: Kind> Deserialize<'de> for Tagged<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let nested =
            |path: &str, message: String| de::Error::custom(format!("{MARK}{path}{MARK}{message}"));
        let types = T::TYPES.join(", ");
        let (tag, rest, at) = match Value::deserialize(d)? {
            Value::String(s) if T::NAMED => (s, Map::new(), ""),
            Value::Object(mut map) => match map.remove("type") {
                Some(Value::String(s)) => (s, map, "type"),
                None | Some(Value::Null) => {
                    let kind = T::KIND;
                    return Err(nested(
                        "type",
                        format!("missing required field (the {kind} type, one of: {types})"),
                    ));
                }
                Some(_) => return Err(nested("type", "expected a string".to_owned())),
            },
            _ if T::NAMED => {
                return Err(de::Error::custom(format!(
                    "expected a {} name ({types}) or an object with \"type\"",
                    T::KIND
                )))
            }
            _ => return Err(de::Error::custom("expected an object")),
        };
        if !T::TYPES.contains(&tag.as_str()) {
            let kind = T::KIND;
            return Err(nested(
                at,
                format!("unknown {kind} type {tag:?}; expected one of: {types}"),
            ));
        }
        let external = Value::Object(Map::from_iter([(tag, Value::Object(rest))]));
        serde_path_to_error::deserialize(external)
            .map(Tagged)
            .map_err(|e| {
                let message = e.inner().to_string();
                let (path, message) = located(e.path().iter().skip(1), message);
                nested(&path, message)
            })
    }
}

/// `path.key`, `path[i]` or `key` at the root.
pub(super) fn join(path: &str, key: &str) -> String {
    match (path.is_empty(), key.starts_with('[') || key.is_empty()) {
        (true, _) => key.to_owned(),
        (false, true) => format!("{path}{key}"),
        (false, false) => format!("{path}.{key}"),
    }
}

/// The field and message of a serde error at `path`: a [`Tagged`] value's inner path is
/// appended, and serde's "missing field `x`" becomes "missing required field" at `x`.
pub(super) fn located<'a>(
    path: impl Iterator<Item = &'a serde_path_to_error::Segment>,
    message: String,
) -> (String, String) {
    use serde_path_to_error::Segment;
    let mut field = String::new();
    for segment in path {
        field = match segment {
            Segment::Seq { index } => format!("{field}[{index}]"),
            Segment::Map { key } | Segment::Enum { variant: key } => join(&field, key),
            Segment::Unknown => join(&field, "?"),
        };
    }
    if let Some((inner, message)) = message.strip_prefix(MARK).and_then(|m| m.split_once(MARK)) {
        return (join(&field, inner), message.to_owned());
    }
    if let Some(key) = message
        .strip_prefix("missing field `")
        .and_then(|m| m.strip_suffix('`'))
    {
        return (join(&field, key), "missing required field".to_owned());
    }
    (field, message)
}

/// The whole file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Scene {
    pub name: String,
    pub description: Option<String>,
    pub size: Option<[U32; 2]>,
    pub camera: Camera,
    pub lights: Vec<Tagged<Light>>,
    pub medium: Medium,
    pub objects: Option<Vec<Object>>,
    pub method: Option<Tagged<Method>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Camera {
    pub eye: Floats<3>,
    pub target: Floats<3>,
    pub up: Option<Floats<3>>,
    pub fov_y_degrees: Num,
    pub near: Num,
    pub far: Option<Num>,
    pub reversed_z: Option<Flag>,
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum Light {
    Point {
        position: Floats<3>,
        intensity: Rgb,
        radius: Option<Num>,
    },
    Spot {
        position: Floats<3>,
        direction: Floats<3>,
        cone_angle_degrees: Num,
        intensity: Rgb,
        texture: Option<Texture>,
        texture_up: Option<Floats<3>>,
        radius: Option<Num>,
    },
    Directional {
        direction: Floats<3>,
        irradiance: Rgb,
        shadow_distance: Option<Num>,
    },
}

impl Kind for Light {
    const KIND: &'static str = "light";
    const TYPES: &'static [&'static str] = &["point", "spot", "directional"];
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum Texture {
    Checkerboard {
        size: U32,
        cells: U32,
        a: Rgb,
        b: Rgb,
    },
    StainedGlass {
        size: U32,
        cells: U32,
        seed: Int,
    },
    File(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Medium {
    pub sigma_s: Option<Rgb>,
    pub sigma_a: Option<Rgb>,
    pub phase: Option<Phase>,
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum Phase {
    Isotropic,
    Rayleigh,
    MieHazy,
    MieMurky,
    HenyeyGreenstein(Num),
    HoffmanPreetham { rayleigh: Rgb, mie: Rgb, g: Num },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Object {
    pub name: Option<String>,
    pub shape: Tagged<Shape>,
    pub transform: Option<Transform>,
    pub casts_shadow: Option<Flag>,
    pub albedo: Option<Rgb>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Transform {
    pub translate: Option<Floats<3>>,
    pub rotate_degrees: Option<Floats<3>>,
    pub scale: Option<Rgb>,
    pub matrix: Option<Floats<16>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum Shape {
    Sphere {
        center: Floats<3>,
        radius: Num,
        segments: Option<U32>,
        rings: Option<U32>,
    },
    Box {
        center: Floats<3>,
        half_extents: Floats<3>,
    },
    Plane {
        center: Floats<3>,
        half_size: Floats<2>,
    },
    Torus {
        center: Floats<3>,
        major_radius: Num,
        minor_radius: Num,
        major_segments: Option<U32>,
        minor_segments: Option<U32>,
    },
    Spring {
        center: Floats<3>,
        coil_radius: Num,
        wire_radius: Num,
        turns: Num,
        height: Num,
        segments_per_turn: Option<U32>,
        wire_segments: Option<U32>,
    },
    Cylinder {
        center: Floats<3>,
        radius: Num,
        half_height: Num,
        segments: Option<U32>,
    },
    Fence {
        center: Option<Floats<3>>,
        posts: U32,
        spacing: Num,
        post_half_extents: Floats<3>,
        rail: Option<Flag>,
    },
    Gltf {
        path: String,
    },
}

impl Kind for Shape {
    const KIND: &'static str = "shape";
    const TYPES: &'static [&'static str] = &[
        "sphere", "box", "plane", "torus", "spring", "cylinder", "fence", "gltf",
    ];
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum Method {
    Reference {},
    Hybrid {
        steps: Option<U32>,
        bisections: Option<U32>,
        scale: Option<U32>,
        upsample: Option<Upsample>,
        texture_steps: Option<U32>,
    },
    Exact {
        steps: Option<U32>,
        bisections: Option<U32>,
        scale: Option<U32>,
        upsample: Option<Upsample>,
        texture_steps: Option<U32>,
        crossings: Option<U32>,
    },
    BruteForce {
        steps: Option<U32>,
        bisections: Option<U32>,
        scale: Option<U32>,
    },
    Textbook {
        steps: Option<U32>,
        scale: Option<U32>,
    },
}

impl Kind for Method {
    const KIND: &'static str = "method";
    const TYPES: &'static [&'static str] =
        &["reference", "hybrid", "exact", "brute_force", "textbook"];
    const NAMED: bool = true;
}

#[derive(Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub(super) enum Upsample {
    Bilinear,
    #[serde(rename = "depth_aware_3x3")]
    DepthAware3x3,
    Separable {
        taps: U32,
        sigma_spatial: Num,
        sigma_depth: Num,
    },
}
