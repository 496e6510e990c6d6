//! A small reader over `serde_json::Value` that keeps the path of every value it reads, so each
//! error names the field it is about (`objects[2].shape.radius`) and never panics.

use glam::{Vec2, Vec3};
use serde_json::{Map, Value};

/// A problem with one field of the file, before the file path is attached.
#[derive(Debug)]
pub(super) struct Problem {
    pub field: String,
    pub problem: String,
    /// An error reported as it is rather than as an [`crate::Error::SceneFile`]: a path that
    /// leads outside the folder, a file that is not regular, a bound of the load passed.
    pub error: Option<Box<crate::Error>>,
}

/// Result of reading part of a scene file.
pub(super) type P<T> = std::result::Result<T, Problem>;

/// A problem at `field`.
pub(super) fn problem(field: &str, problem: impl Into<String>) -> Problem {
    Problem {
        field: if field.is_empty() {
            "(root)".to_owned()
        } else {
            field.to_owned()
        },
        problem: problem.into(),
        error: None,
    }
}

/// `path.key`, or `key` at the root.
pub(super) fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_owned()
    } else {
        format!("{path}.{key}")
    }
}

/// `path[i]`.
pub(super) fn index(path: &str, i: usize) -> String {
    format!("{path}[{i}]")
}

/// A short description of a JSON value for "expected X, got Y" messages.
pub(super) fn describe(v: &Value) -> String {
    match v {
        Value::Null => "null".to_owned(),
        Value::Bool(b) => format!("a boolean ({b})"),
        Value::Number(n) => format!("a number ({n})"),
        Value::String(s) => {
            let short: String = s.chars().take(40).collect();
            let dots = if short.len() < s.len() { "..." } else { "" };
            format!("a string ({short:?}{dots})")
        }
        Value::Array(a) => format!("an array of {} elements", a.len()),
        Value::Object(_) => "an object".to_owned(),
    }
}

/// Wrong-type problem.
pub(super) fn expected(path: &str, what: &str, v: &Value) -> Problem {
    problem(path, format!("expected {what}, got {}", describe(v)))
}

/// Checks a condition, or fails with `message` at `path`.
pub(super) fn ensure(ok: bool, path: &str, message: impl FnOnce() -> String) -> P<()> {
    if ok {
        Ok(())
    } else {
        Err(problem(path, message()))
    }
}

/// A JSON object being read, with its path and the keys it may contain.
pub(super) struct Obj<'a> {
    map: &'a Map<String, Value>,
    path: String,
}

impl<'a> Obj<'a> {
    /// `v` as an object whose keys are all in `allowed` (the first unknown key is an error).
    pub fn new(v: &'a Value, path: &str, allowed: &[&str]) -> P<Self> {
        let map = v
            .as_object()
            .ok_or_else(|| expected(path, "an object", v))?;
        if let Some(key) = map.keys().find(|k| !allowed.contains(&k.as_str())) {
            return Err(problem(
                &join(path, key),
                format!("unknown field; expected one of: {}", allowed.join(", ")),
            ));
        }
        Ok(Self {
            map,
            path: path.to_owned(),
        })
    }

    /// The path of `key` in this object.
    pub fn field(&self, key: &str) -> String {
        join(&self.path, key)
    }

    /// The value of `key`; `None` when absent or `null`.
    pub fn value(&self, key: &str) -> Option<&'a Value> {
        self.map.get(key).filter(|v| !v.is_null())
    }

    /// Whether `key` is present and not `null`.
    pub fn has(&self, key: &str) -> bool {
        self.value(key).is_some()
    }

    /// The value of a required `key`.
    pub fn req_value(&self, key: &str) -> P<&'a Value> {
        self.value(key)
            .ok_or_else(|| problem(&self.field(key), "missing required field"))
    }

    /// A required field.
    pub fn req<T: FromJson>(&self, key: &str) -> P<T> {
        T::from_json(self.req_value(key)?, &self.field(key))
    }

    /// An optional field (`null` counts as absent).
    pub fn opt<T: FromJson>(&self, key: &str) -> P<Option<T>> {
        self.value(key)
            .map(|v| T::from_json(v, &self.field(key)))
            .transpose()
    }

    /// An optional field with a default.
    pub fn or<T: FromJson>(&self, key: &str, default: T) -> P<T> {
        Ok(self.opt(key)?.unwrap_or(default))
    }
}

/// Reads the `"type"` tag of an object, checking it against `types`.
pub(super) fn tag<'a>(v: &'a Value, path: &str, kind: &str, types: &[&str]) -> P<&'a str> {
    let map = v
        .as_object()
        .ok_or_else(|| expected(path, "an object", v))?;
    let field = join(path, "type");
    let t = match map.get("type") {
        None | Some(Value::Null) => {
            return Err(problem(
                &field,
                format!(
                    "missing required field (the {kind} type, one of: {})",
                    types.join(", ")
                ),
            ))
        }
        Some(Value::String(s)) => s.as_str(),
        Some(other) => return Err(expected(&field, "a string", other)),
    };
    if !types.contains(&t) {
        return Err(problem(
            &field,
            format!(
                "unknown {kind} type {t:?}; expected one of: {}",
                types.join(", ")
            ),
        ));
    }
    Ok(t)
}

/// The elements of an array, with their paths.
pub(super) fn array<'a>(v: &'a Value, path: &str) -> P<Vec<(&'a Value, String)>> {
    let a = v.as_array().ok_or_else(|| expected(path, "an array", v))?;
    Ok(a.iter()
        .enumerate()
        .map(|(i, e)| (e, index(path, i)))
        .collect())
}

/// Conversion of one JSON value, with its path for errors.
pub(super) trait FromJson: Sized {
    /// Reads `v`, found at `path`.
    fn from_json(v: &Value, path: &str) -> P<Self>;
}

impl FromJson for f64 {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        let x = v.as_f64().ok_or_else(|| expected(path, "a number", v))?;
        ensure(x.is_finite(), path, || format!("must be finite, got {x}"))?;
        Ok(x)
    }
}

impl FromJson for f32 {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        let x = f64::from_json(v, path)?;
        ensure(x.abs() <= f64::from(f32::MAX), path, || {
            format!("{x} is out of range for a 32-bit float")
        })?;
        Ok(x as f32)
    }
}

/// A non-negative integer that fits in u64 (JSON integers, or floats with no fraction).
fn integer(v: &Value, path: &str) -> P<u64> {
    if let Some(n) = v.as_u64() {
        return Ok(n);
    }
    match v.as_f64() {
        Some(x) if x >= 0.0 && x.fract() == 0.0 && x <= 9_007_199_254_740_992.0 => Ok(x as u64),
        Some(x) => Err(problem(
            path,
            format!("expected a non-negative integer, got {x}"),
        )),
        None => Err(expected(path, "a non-negative integer", v)),
    }
}

impl FromJson for u64 {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        integer(v, path)
    }
}

impl FromJson for u32 {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        let n = integer(v, path)?;
        u32::try_from(n)
            .map_err(|_| problem(path, format!("{n} is out of range (at most {})", u32::MAX)))
    }
}

impl FromJson for bool {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        v.as_bool()
            .ok_or_else(|| expected(path, "true or false", v))
    }
}

impl FromJson for String {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        v.as_str()
            .map(str::to_owned)
            .ok_or_else(|| expected(path, "a string", v))
    }
}

/// Exactly `N` numbers.
fn floats<const N: usize>(v: &Value, path: &str) -> P<[f32; N]> {
    let what = format!("an array of {N} numbers");
    let a = v.as_array().ok_or_else(|| expected(path, &what, v))?;
    ensure(a.len() == N, path, || {
        format!("expected {what}, got {} elements", a.len())
    })?;
    let mut out = [0.0; N];
    for (i, (o, e)) in out.iter_mut().zip(a).enumerate() {
        *o = f32::from_json(e, &index(path, i))?;
    }
    Ok(out)
}

impl FromJson for Vec3 {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        floats::<3>(v, path).map(Vec3::from_array)
    }
}

impl FromJson for Vec2 {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        floats::<2>(v, path).map(Vec2::from_array)
    }
}

impl FromJson for [f32; 16] {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        floats::<16>(v, path)
    }
}

/// A colour or per-channel coefficient: `[r, g, b]` or one number for all three channels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Rgb(pub Vec3);

impl FromJson for Rgb {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        if v.is_number() {
            return f32::from_json(v, path).map(|x| Rgb(Vec3::splat(x)));
        }
        if !v.is_array() {
            return Err(expected(path, "a number or an array of 3 numbers", v));
        }
        Vec3::from_json(v, path).map(Rgb)
    }
}

/// A scale factor: one number or `[x, y, z]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Scale3(pub Vec3);

impl FromJson for Scale3 {
    fn from_json(v: &Value, path: &str) -> P<Self> {
        Rgb::from_json(v, path).map(|Rgb(s)| Scale3(s))
    }
}
