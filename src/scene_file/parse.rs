//! Reading each section of a scene file into the scene types, with a field path on every
//! error. Everything a constructor further down would panic on (the procedural shapes assert
//! their parameters) is checked here first.

use std::path::{Path, PathBuf};

use glam::camera::rh::{proj::directx, view::look_at_mat4};
use glam::{Mat4, Vec2, Vec3};
use serde_json::Value;

use super::json::{array, ensure, expected, problem, tag, FromJson, Obj, Rgb, Scale3, P};
use super::{stained_glass, Method, SceneDescription, SceneLight, SceneObject};
use crate::load::{Budget, Limit};
use crate::nodes::{Scale, UpsampleFilter};
use crate::scene::{
    shapes, Camera, Light, LightTexture, Medium, Mesh, PhaseFunction, PointLight, SpotLight,
};

/// Largest output width or height.
const MAX_SIZE: u32 = 8192;
/// Largest light texture width or height built from a scene file.
const MAX_TEXTURE: u32 = 4096;
/// Largest coordinate magnitude of points, and largest length.
const MAX_COORD: f32 = 1e6;
/// Smallest length.
const MIN_LENGTH: f32 = 1e-6;
/// Largest segment count of a procedural shape.
const MAX_SEGMENTS: u32 = 1024;

/// A crate error from a constructor, reported at `path`.
fn from_error(path: &str) -> impl FnOnce(crate::Error) -> super::json::Problem + '_ {
    move |e| problem(path, e.to_string())
}

/// A crate error from loading a file or counting a total: the errors of [`crate::load`] are
/// kept as they are, others are reported at `path`.
fn from_load_error(path: &str) -> impl FnOnce(crate::Error) -> super::json::Problem + '_ {
    move |e| match e {
        crate::Error::PathOutsideFolder { .. }
        | crate::Error::NotRegularFile { .. }
        | crate::Error::LimitExceeded { .. } => super::json::Problem {
            field: path.to_owned(),
            problem: e.to_string(),
            error: Some(Box::new(e)),
        },
        e => problem(path, e.to_string()),
    }
}

/// What parsing a scene needs besides the JSON: where its files are and the load's totals.
pub(super) struct Ctx<'a> {
    /// The canonical folder of the scene file, or why it could not be found.
    #[cfg_attr(not(any(feature = "gltf", feature = "image")), allow(dead_code))]
    pub folder: std::result::Result<PathBuf, String>,
    /// The scene file as errors name it.
    pub file: &'a str,
    /// The load's running totals.
    pub budget: Budget,
}

impl Ctx<'_> {
    /// Counts `n` more of `limit` (reported at `path` if it passes its bound).
    fn add(&mut self, limit: Limit, n: u64, path: &str) -> P<()> {
        self.budget
            .add(limit, n, self.file)
            .map_err(from_load_error(path))
    }

    /// Checks that `n` more of `limit` fit, before building them.
    fn check(&self, limit: Limit, n: u64, path: &str) -> P<()> {
        self.budget
            .check(limit, n, self.file)
            .map_err(from_load_error(path))
    }

    /// Reads the file named `named` at `path`: confined to the scene's folder unless allowed.
    #[cfg_attr(not(any(feature = "gltf", feature = "image")), allow(dead_code))]
    fn read(&mut self, named: &str, path: &str) -> P<(PathBuf, Vec<u8>)> {
        let folder = self
            .folder
            .as_ref()
            .map_err(|e| problem(path, format!("cannot resolve {named:?}: {e}")))?;
        crate::load::read_named(&mut self.budget, folder, Path::new(named), self.file, path)
            .map_err(from_load_error(path))
    }
}

/// A point: finite, each coordinate within ±[`MAX_COORD`].
fn point(v: &Value, path: &str) -> P<Vec3> {
    let p = Vec3::from_json(v, path)?;
    ensure(p.abs().max_element() <= MAX_COORD, path, || {
        format!("coordinates must be within ±{MAX_COORD:e}, got {p}")
    })?;
    Ok(p)
}

fn req_point(o: &Obj, key: &str) -> P<Vec3> {
    point(o.req_value(key)?, &o.field(key))
}

fn opt_point(o: &Obj, key: &str) -> P<Option<Vec3>> {
    o.value(key).map(|v| point(v, &o.field(key))).transpose()
}

/// A length in [[`MIN_LENGTH`], [`MAX_COORD`]].
fn check_length(x: f32, path: &str) -> P<f32> {
    ensure((MIN_LENGTH..=MAX_COORD).contains(&x), path, || {
        format!("must be in [{MIN_LENGTH:e}, {MAX_COORD:e}], got {x}")
    })?;
    Ok(x)
}

fn length(o: &Obj, key: &str) -> P<f32> {
    check_length(o.req(key)?, &o.field(key))
}

fn lengths(o: &Obj, key: &str) -> P<Vec3> {
    let v: Vec3 = o.req(key)?;
    for (i, x) in v.to_array().into_iter().enumerate() {
        check_length(x, &format!("{}[{i}]", o.field(key)))?;
    }
    Ok(v)
}

/// An optional count in `min..=max`, with a default.
fn count(o: &Obj, key: &str, default: u32, min: u32, max: u32) -> P<u32> {
    let n = o.or(key, default)?;
    ensure((min..=max).contains(&n), &o.field(key), || {
        format!("must be in {min}..={max}, got {n}")
    })?;
    Ok(n)
}

/// RGB, each channel >= 0.
fn non_negative(v: &Value, path: &str) -> P<Vec3> {
    let Rgb(c) = Rgb::from_json(v, path)?;
    ensure(c.min_element() >= 0.0, path, || {
        format!("must be >= 0, got {c}")
    })?;
    Ok(c)
}

/// A Henyey–Greenstein asymmetry in (−1, 1).
fn asymmetry(v: &Value, path: &str) -> P<f32> {
    let g = f32::from_json(v, path)?;
    ensure(g.abs() < 1.0, path, || {
        format!("the asymmetry g must be in (-1, 1), got {g}")
    })?;
    Ok(g)
}

/// The whole file.
pub(super) fn scene(root: &Value, ctx: &mut Ctx) -> P<SceneDescription> {
    let o = Obj::new(
        root,
        "",
        &[
            "name",
            "description",
            "size",
            "camera",
            "lights",
            "medium",
            "objects",
            "method",
        ],
    )?;
    let name: String = o.req("name")?;
    let description: Option<String> = o.opt("description")?;
    let size = match o.value("size") {
        None => (512, 512),
        Some(v) => size(v, &o.field("size"))?,
    };
    let camera = camera(o.req_value("camera")?, &o.field("camera"), size)?;

    let lights_path = o.field("lights");
    let items = array(o.req_value("lights")?, &lights_path)?;
    ctx.add(Limit::Lights, items.len() as u64, &lights_path)?;
    let mut lights = Vec::with_capacity(items.len());
    for (v, path) in items {
        lights.push(light(v, &path, ctx)?);
    }
    ensure(!lights.is_empty(), &lights_path, || {
        "must contain at least one light".to_owned()
    })?;

    let medium = medium(o.req_value("medium")?, &o.field("medium"))?;

    let mut objects = Vec::new();
    if let Some(v) = o.value("objects") {
        for (i, (v, path)) in array(v, &o.field("objects"))?.into_iter().enumerate() {
            object(v, &path, i, ctx, &mut objects)?;
        }
    }

    let method = match o.value("method") {
        None => Method::default(),
        Some(v) => method(v, &o.field("method"))?,
    };
    Ok(SceneDescription {
        name,
        description,
        size,
        camera,
        lights,
        medium,
        objects,
        method,
    })
}

fn size(v: &Value, path: &str) -> P<(u32, u32)> {
    let a = v
        .as_array()
        .ok_or_else(|| expected(path, "[width, height]", v))?;
    ensure(a.len() == 2, path, || {
        format!("expected [width, height], got {} elements", a.len())
    })?;
    let mut out = [0u32; 2];
    for (i, (o, e)) in out.iter_mut().zip(a).enumerate() {
        let field = format!("{path}[{i}]");
        *o = u32::from_json(e, &field)?;
        ensure((1..=MAX_SIZE).contains(o), &field, || {
            format!("must be in 1..={MAX_SIZE}, got {o}")
        })?;
    }
    Ok((out[0], out[1]))
}

fn camera(v: &Value, path: &str, (width, height): (u32, u32)) -> P<Camera> {
    let c = Obj::new(
        v,
        path,
        &[
            "eye",
            "target",
            "up",
            "fov_y_degrees",
            "near",
            "far",
            "reversed_z",
        ],
    )?;
    let eye = req_point(&c, "eye")?;
    let target = req_point(&c, "target")?;
    let up: Vec3 = c.or("up", Vec3::Y)?;
    let fov: f32 = c.req("fov_y_degrees")?;
    ensure(fov > 0.0 && fov < 180.0, &c.field("fov_y_degrees"), || {
        format!("must be in (0, 180), got {fov}")
    })?;
    let near = length(&c, "near")?;
    let far: Option<f32> = c.opt("far")?;
    if let Some(far) = far {
        ensure(
            far > near && far <= MAX_COORD * 1e3,
            &c.field("far"),
            || {
                format!(
                "must be greater than near ({near}) and at most {:e}, or null for an infinite far plane; got {far}",
                MAX_COORD * 1e3
            )
            },
        )?;
    }
    let reversed: bool = c.or("reversed_z", false)?;

    let forward = target - eye;
    ensure(forward.length() > 0.0, &c.field("target"), || {
        "must differ from eye".to_owned()
    })?;
    let up = up.normalize_or_zero();
    ensure(up != Vec3::ZERO, &c.field("up"), || {
        "must be non-zero".to_owned()
    })?;
    ensure(
        forward.normalize().cross(up).length() > 1e-3,
        &c.field("up"),
        || "must not be parallel to the view direction (target - eye)".to_owned(),
    )?;
    let view = look_at_mat4(eye, target, up);
    let fov = fov.to_radians();
    let aspect = width as f32 / height as f32;
    let projection = match (far, reversed) {
        (None, false) => directx::perspective_infinite(fov, aspect, near),
        (None, true) => directx::perspective_infinite_reverse(fov, aspect, near),
        (Some(far), false) => directx::perspective(fov, aspect, near, far),
        (Some(far), true) => directx::perspective(fov, aspect, far, near),
    };
    Camera::new(view, projection).map_err(from_error(path))
}

fn intensity(o: &Obj) -> P<Vec3> {
    let path = o.field("intensity");
    let i = non_negative(o.req_value("intensity")?, &path)?;
    ensure(i.max_element() > 0.0, &path, || {
        "is zero in every channel: the light would contribute nothing".to_owned()
    })?;
    Ok(i)
}

fn light(v: &Value, path: &str, ctx: &mut Ctx) -> P<SceneLight> {
    match tag(v, path, "light", &["point", "spot"])? {
        "point" => {
            let o = Obj::new(v, path, &["type", "position", "intensity"])?;
            let position = req_point(&o, "position")?;
            let intensity = intensity(&o)?;
            let light = PointLight::new(position, intensity).map_err(from_error(path))?;
            Ok(SceneLight {
                light: Light::Point(light),
                texture: None,
            })
        }
        _ => {
            let o = Obj::new(
                v,
                path,
                &[
                    "type",
                    "position",
                    "direction",
                    "cone_angle_degrees",
                    "intensity",
                    "texture",
                ],
            )?;
            let position = req_point(&o, "position")?;
            let direction: Vec3 = o.req("direction")?;
            ensure(
                direction.length().is_finite() && direction.length() > 0.0,
                &o.field("direction"),
                || format!("must be a non-zero finite vector, got {direction}"),
            )?;
            let cone: f32 = o.req("cone_angle_degrees")?;
            ensure(
                cone > 0.0 && cone < 180.0,
                &o.field("cone_angle_degrees"),
                || format!("must be in (0, 180), got {cone}"),
            )?;
            let intensity = intensity(&o)?;
            let texture = o
                .value("texture")
                .map(|t| texture(t, &o.field("texture"), ctx))
                .transpose()?;
            let light = SpotLight::new(position, direction, cone.to_radians(), intensity)
                .map_err(from_error(path))?;
            Ok(SceneLight {
                light: Light::Spot(light),
                texture,
            })
        }
    }
}

/// An object with exactly one key: `{"kind": value}`; returns the key, its value and path.
fn single_key<'a>(v: &'a Value, path: &str, kinds: &[&str]) -> P<(&'a str, &'a Value, String)> {
    let what = format!("an object with one of the keys: {}", kinds.join(", "));
    let map = v.as_object().ok_or_else(|| expected(path, &what, v))?;
    let mut entries = map.iter();
    let (Some((key, value)), None) = (entries.next(), entries.next()) else {
        return Err(problem(
            path,
            format!("expected {what}, got an object with {} keys", map.len()),
        ));
    };
    let field = super::json::join(path, key);
    ensure(kinds.contains(&key.as_str()), &field, || {
        format!("unknown field; expected one of: {}", kinds.join(", "))
    })?;
    Ok((key.as_str(), value, field))
}

fn texture_size(o: &Obj) -> P<(u32, u32)> {
    let size: u32 = o.req("size")?;
    ensure((1..=MAX_TEXTURE).contains(&size), &o.field("size"), || {
        format!("must be in 1..={MAX_TEXTURE}, got {size}")
    })?;
    let cells: u32 = o.req("cells")?;
    ensure((1..=size).contains(&cells), &o.field("cells"), || {
        format!("must be in 1..={size} (the texture size), got {cells}")
    })?;
    Ok((size, cells))
}

fn texture(v: &Value, path: &str, ctx: &mut Ctx) -> P<LightTexture> {
    let (kind, value, field) = single_key(v, path, &["checkerboard", "stained_glass", "file"])?;
    match kind {
        "checkerboard" => {
            let o = Obj::new(value, &field, &["size", "cells", "a", "b"])?;
            let (size, cells) = texture_size(&o)?;
            ctx.add(
                Limit::Texels,
                u64::from(size) * u64::from(size),
                &o.field("size"),
            )?;
            let a = non_negative(o.req_value("a")?, &o.field("a"))?;
            let b = non_negative(o.req_value("b")?, &o.field("b"))?;
            LightTexture::checkerboard(size, cells, a, b).map_err(from_error(&field))
        }
        "stained_glass" => {
            let o = Obj::new(value, &field, &["size", "cells", "seed"])?;
            let (size, cells) = texture_size(&o)?;
            ctx.add(
                Limit::Texels,
                u64::from(size) * u64::from(size),
                &o.field("size"),
            )?;
            let seed: u64 = o.req("seed")?;
            stained_glass(size, cells, seed).map_err(from_error(&field))
        }
        _ => {
            let file = String::from_json(value, &field)?;
            image_file(&file, &field, ctx)
        }
    }
}

#[cfg(feature = "image")]
fn image_file(file: &str, field: &str, ctx: &mut Ctx) -> P<LightTexture> {
    let (path, bytes) = ctx.read(file, field)?;
    LightTexture::from_image_bytes(&bytes, &path.display().to_string(), &mut ctx.budget)
        .map_err(from_load_error(field))
}

#[cfg(not(feature = "image"))]
fn image_file(file: &str, field: &str, _ctx: &mut Ctx) -> P<LightTexture> {
    Err(problem(
        field,
        format!("cannot load {file:?}: volshadow was built without the `image` feature"),
    ))
}

fn medium(v: &Value, path: &str) -> P<Medium> {
    let o = Obj::new(v, path, &["sigma_s", "sigma_a", "phase"])?;
    let sigma_s = o
        .value("sigma_s")
        .map(|v| non_negative(v, &o.field("sigma_s")))
        .transpose()?;
    let sigma_a = match o.value("sigma_a") {
        None => Vec3::ZERO,
        Some(v) => non_negative(v, &o.field("sigma_a"))?,
    };
    let phase = match o.value("phase") {
        None => PhaseFunction::Isotropic,
        Some(v) => phase(v, &o.field("phase"))?,
    };
    if let PhaseFunction::HoffmanPreetham { rayleigh, mie, g } = phase {
        ensure(sigma_s.is_none(), &o.field("sigma_s"), || {
            "must not be given with the hoffman_preetham phase, which sets sigma_s = rayleigh + mie"
                .to_owned()
        })?;
        return Medium::hoffman_preetham(rayleigh, mie, g, sigma_a)
            .map_err(from_error(&o.field("phase")));
    }
    let sigma_s = sigma_s.ok_or_else(|| {
        problem(
            &o.field("sigma_s"),
            "missing required field (unless the phase is hoffman_preetham)",
        )
    })?;
    Medium::new(sigma_s, sigma_a, phase).map_err(from_error(path))
}

fn phase(v: &Value, path: &str) -> P<PhaseFunction> {
    const NAMES: [&str; 4] = ["isotropic", "rayleigh", "mie_hazy", "mie_murky"];
    if let Some(name) = v.as_str() {
        return match name {
            "isotropic" => Ok(PhaseFunction::Isotropic),
            "rayleigh" => Ok(PhaseFunction::Rayleigh),
            "mie_hazy" => Ok(PhaseFunction::MieHazy),
            "mie_murky" => Ok(PhaseFunction::MieMurky),
            other => Err(problem(
                path,
                format!(
                    "unknown phase function {other:?}; expected one of: {}, or {{\"henyey_greenstein\": g}}, {{\"hoffman_preetham\": {{...}}}}",
                    NAMES.join(", ")
                ),
            )),
        };
    }
    let (kind, value, field) = single_key(v, path, &["henyey_greenstein", "hoffman_preetham"])
        .map_err(|mut p| {
            if !v.is_object() {
                p.problem = format!(
                    "expected one of {} or an object {{\"henyey_greenstein\": g}} or {{\"hoffman_preetham\": {{...}}}}, got {}",
                    NAMES.join(", "),
                    super::json::describe(v)
                );
            }
            p
        })?;
    if kind == "henyey_greenstein" {
        let g = asymmetry(value, &field)?;
        return Ok(PhaseFunction::HenyeyGreenstein { g });
    }
    let o = Obj::new(value, &field, &["rayleigh", "mie", "g"])?;
    let rayleigh = non_negative(o.req_value("rayleigh")?, &o.field("rayleigh"))?;
    let mie = non_negative(o.req_value("mie")?, &o.field("mie"))?;
    let g = asymmetry(o.req_value("g")?, &o.field("g"))?;
    let sum = rayleigh + mie;
    ensure(sum.min_element() > 0.0, &field, || {
        format!("rayleigh + mie must be > 0 in every channel, got {sum}")
    })?;
    Ok(PhaseFunction::HoffmanPreetham { rayleigh, mie, g })
}

fn transform(v: &Value, path: &str) -> P<Mat4> {
    let o = Obj::new(v, path, &["translate", "rotate_degrees", "scale", "matrix"])?;
    let m = if o.has("matrix") {
        if let Some(other) = ["translate", "rotate_degrees", "scale"]
            .into_iter()
            .find(|k| o.has(k))
        {
            return Err(problem(&o.field(other), "cannot be combined with `matrix`"));
        }
        let field = o.field("matrix");
        let m = Mat4::from_cols_array(&o.req("matrix")?);
        ensure(
            m.row(3) == glam::Vec4::new(0.0, 0.0, 0.0, 1.0),
            &field,
            || {
                format!(
                    "must be affine (column-major; the last row must be 0, 0, 0, 1), got last row {}",
                    m.row(3)
                )
            },
        )?;
        ensure(
            m.w_axis.truncate().abs().max_element() <= MAX_COORD,
            &field,
            || format!("its translation must be within ±{MAX_COORD:e}"),
        )?;
        m
    } else {
        let translate = opt_point(&o, "translate")?.unwrap_or(Vec3::ZERO);
        let rotate: Vec3 = o.or("rotate_degrees", Vec3::ZERO)?;
        ensure(
            rotate.abs().max_element() <= 36_000.0,
            &o.field("rotate_degrees"),
            || format!("angles must be within ±36000 degrees, got {rotate}"),
        )?;
        let Scale3(scale) = o.or("scale", Scale3(Vec3::ONE))?;
        ensure(
            scale.min_element() >= MIN_LENGTH && scale.max_element() <= MAX_COORD,
            &o.field("scale"),
            || {
                format!("must be in [{MIN_LENGTH:e}, {MAX_COORD:e}] (mirroring is not allowed), got {scale}")
            },
        )?;
        let r = Vec3::new(
            rotate.x.to_radians(),
            rotate.y.to_radians(),
            rotate.z.to_radians(),
        );
        Mat4::from_translation(translate)
            * Mat4::from_rotation_z(r.z)
            * Mat4::from_rotation_y(r.y)
            * Mat4::from_rotation_x(r.x)
            * Mat4::from_scale(scale)
    };
    check_transform(m, path)?;
    Ok(m)
}

/// A usable object transform: finite, affine, invertible, positive determinant (the check
/// [`crate::Occluder`] makes too).
fn check_transform(m: Mat4, path: &str) -> P<()> {
    crate::scene::check_object_transform(m).map_err(|p| problem(path, p.to_string()))
}

/// Shapes built at the origin (where every parameter the checks allow gives a valid mesh), then
/// moved to `center` through [`Mesh::new`], which reports instead of panicking if f32 rounding
/// collapses them there.
fn placed(mesh: Mesh, center: Vec3, path: &str) -> P<Mesh> {
    if center == Vec3::ZERO {
        return Ok(mesh);
    }
    let positions: Vec<Vec3> = mesh.positions().iter().map(|&p| p + center).collect();
    Mesh::new(&positions, mesh.indices()).map_err(from_error(path))
}

/// What a `shape` produces: one mesh, or (glTF) several with their own names and transforms.
enum Shape {
    One(Mesh),
    Many(Vec<(String, Mesh, Mat4)>),
}

const SHAPES: [&str; 8] = [
    "sphere", "box", "plane", "torus", "spring", "cylinder", "fence", "gltf",
];

fn shape(v: &Value, path: &str, ctx: &mut Ctx) -> P<(&'static str, Shape)> {
    let kind = tag(v, path, "shape", &SHAPES)?;
    let kind = SHAPES.into_iter().find(|k| *k == kind).unwrap_or("shape");
    let mesh = match kind {
        "sphere" => {
            let o = Obj::new(v, path, &["type", "center", "radius", "segments", "rings"])?;
            let center = req_point(&o, "center")?;
            let radius = length(&o, "radius")?;
            let segments = count(&o, "segments", 32, 3, MAX_SEGMENTS)?;
            let rings = count(&o, "rings", 16, 2, MAX_SEGMENTS)?;
            ctx.check(
                Limit::Triangles,
                2 * u64::from(segments) * u64::from(rings - 1),
                path,
            )?;
            placed(
                shapes::uv_sphere(Vec3::ZERO, radius, segments, rings),
                center,
                path,
            )?
        }
        "box" => {
            let o = Obj::new(v, path, &["type", "center", "half_extents"])?;
            let center = req_point(&o, "center")?;
            let half = lengths(&o, "half_extents")?;
            placed(shapes::cuboid(Vec3::ZERO, half), center, path)?
        }
        "plane" => {
            let o = Obj::new(v, path, &["type", "center", "half_size"])?;
            let center = req_point(&o, "center")?;
            let half: Vec2 = o.req("half_size")?;
            for (i, x) in half.to_array().into_iter().enumerate() {
                check_length(x, &format!("{}[{i}]", o.field("half_size")))?;
            }
            placed(shapes::plane(Vec3::ZERO, half), center, path)?
        }
        "torus" => {
            let o = Obj::new(
                v,
                path,
                &[
                    "type",
                    "center",
                    "major_radius",
                    "minor_radius",
                    "major_segments",
                    "minor_segments",
                ],
            )?;
            let center = req_point(&o, "center")?;
            let major = length(&o, "major_radius")?;
            let minor = length(&o, "minor_radius")?;
            ensure(
                minor < major && minor >= 1e-4 * major,
                &o.field("minor_radius"),
                || {
                    format!(
                        "must be below major_radius ({major}) and at least 1e-4 of it, got {minor}"
                    )
                },
            )?;
            let m = count(&o, "major_segments", 48, 3, MAX_SEGMENTS)?;
            let n = count(&o, "minor_segments", 16, 3, MAX_SEGMENTS)?;
            ctx.check(Limit::Triangles, 2 * u64::from(m) * u64::from(n), path)?;
            placed(shapes::torus(Vec3::ZERO, major, minor, m, n), center, path)?
        }
        "spring" => {
            let o = Obj::new(
                v,
                path,
                &[
                    "type",
                    "center",
                    "coil_radius",
                    "wire_radius",
                    "turns",
                    "height",
                    "segments_per_turn",
                    "wire_segments",
                ],
            )?;
            let center = req_point(&o, "center")?;
            let coil = length(&o, "coil_radius")?;
            let wire = length(&o, "wire_radius")?;
            let turns: f32 = o.req("turns")?;
            ensure((0.01..=1000.0).contains(&turns), &o.field("turns"), || {
                format!("must be in [0.01, 1000], got {turns}")
            })?;
            let height = length(&o, "height")?;
            ensure(
                wire >= 1e-4 * coil.max(height),
                &o.field("wire_radius"),
                || {
                    format!(
                        "must be at least 1e-4 of coil_radius and height ({}), got {wire}",
                        coil.max(height)
                    )
                },
            )?;
            let per_turn = count(&o, "segments_per_turn", 32, 3, 256)?;
            let wire_segments = count(&o, "wire_segments", 12, 3, 64)?;
            ensure(
                turns * per_turn as f32 <= 16384.0,
                &o.field("segments_per_turn"),
                || {
                    format!(
                        "turns × segments_per_turn must be at most 16384, got {}",
                        turns * per_turn as f32
                    )
                },
            )?;
            // (steps + 1) wire rings of `wire_segments` quads, and two end caps.
            let steps = ((turns * per_turn as f32).ceil() as u64).max(1);
            ctx.check(
                Limit::Triangles,
                2 * (steps + 1) * u64::from(wire_segments),
                path,
            )?;
            placed(
                shapes::helix_spring(
                    Vec3::ZERO,
                    coil,
                    wire,
                    turns,
                    height,
                    per_turn,
                    wire_segments,
                ),
                center,
                path,
            )?
        }
        "cylinder" => {
            let o = Obj::new(
                v,
                path,
                &["type", "center", "radius", "half_height", "segments"],
            )?;
            let center = req_point(&o, "center")?;
            let radius = length(&o, "radius")?;
            let half_height = length(&o, "half_height")?;
            let segments = count(&o, "segments", 32, 3, MAX_SEGMENTS)?;
            ctx.check(Limit::Triangles, 2 * u64::from(segments), path)?;
            placed(
                shapes::cylinder_open(Vec3::ZERO, radius, half_height, segments),
                center,
                path,
            )?
        }
        "fence" => fence(v, path, ctx)?,
        _ => return gltf(v, path, ctx).map(|m| ("gltf", Shape::Many(m))),
    };
    ctx.add(Limit::Triangles, mesh.triangle_count() as u64, path)?;
    Ok((kind, Shape::One(mesh)))
}

fn fence(v: &Value, path: &str, ctx: &Ctx) -> P<Mesh> {
    let o = Obj::new(
        v,
        path,
        &[
            "type",
            "center",
            "posts",
            "spacing",
            "post_half_extents",
            "rail",
        ],
    )?;
    let center = opt_point(&o, "center")?.unwrap_or(Vec3::ZERO);
    let posts: u32 = o.req("posts")?;
    ensure((1..=1024).contains(&posts), &o.field("posts"), || {
        format!("must be in 1..=1024, got {posts}")
    })?;
    let spacing = length(&o, "spacing")?;
    let half = lengths(&o, "post_half_extents")?;
    let rail: bool = o.or("rail", false)?;
    // 12 triangles per box: the posts and two rails.
    ctx.check(Limit::Triangles, 12 * (u64::from(posts) + 2), path)?;

    let mut boxes: Vec<(Vec3, Vec3)> = (0..posts)
        .map(|k| {
            let x = (k as f32 - 0.5 * (posts - 1) as f32) * spacing;
            (center + Vec3::X * x, half)
        })
        .collect();
    if rail && posts > 1 {
        let run = 0.5 * (posts - 1) as f32 * spacing;
        let rail_half = Vec3::new(run + 0.5 * half.x, 0.6 * half.x.min(half.y), 0.5 * half.z);
        for fraction in [0.3, 0.75] {
            let y = center.y - half.y + 2.0 * half.y * fraction;
            boxes.push((Vec3::new(center.x, y, center.z), rail_half));
        }
    }
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for (c, h) in boxes {
        let b = shapes::cuboid(Vec3::ZERO, h);
        let base = positions.len() as u32;
        positions.extend(b.positions().iter().map(|&p| p + c));
        indices.extend(b.indices().iter().map(|&i| i + base));
    }
    Mesh::new(&positions, &indices).map_err(from_error(path))
}

#[cfg(feature = "gltf")]
fn gltf(v: &Value, path: &str, ctx: &mut Ctx) -> P<Vec<(String, Mesh, Mat4)>> {
    let o = Obj::new(v, path, &["type", "path"])?;
    let file: String = o.req("path")?;
    let field = o.field("path");
    let folder = ctx
        .folder
        .as_ref()
        .map_err(|e| problem(&field, format!("cannot resolve {file:?}: {e}")))?;
    let file =
        match crate::load::resolve(folder, Path::new(&file), ctx.budget.options.allow_outside) {
            crate::load::Resolved::Path(p) => p,
            crate::load::Resolved::Outside => {
                return Err(from_load_error(&field)(crate::Error::PathOutsideFolder {
                    file: ctx.file.to_owned(),
                    field: field.clone(),
                    target: file,
                }))
            }
        };
    // Its triangles and placed meshes count into the scene's totals.
    let meshes =
        crate::gltf::load_budgeted(&file, &mut ctx.budget).map_err(from_load_error(&field))?;
    ensure(!meshes.is_empty(), &o.field("path"), || {
        "the glTF file contains no meshes".to_owned()
    })?;
    // A mesh's name when it names one primitive alone, else its index (and name).
    let unique = |name: &Option<String>| meshes.iter().filter(|m| &m.name == name).count() == 1;
    let names: Vec<String> = meshes
        .iter()
        .enumerate()
        .map(|(i, m)| match &m.name {
            Some(name) if unique(&m.name) => name.clone(),
            Some(name) => format!("{i}:{name}"),
            None => i.to_string(),
        })
        .collect();
    Ok(names
        .into_iter()
        .zip(meshes)
        .map(|(name, m)| (name, m.mesh, m.transform))
        .collect())
}

#[cfg(not(feature = "gltf"))]
fn gltf(v: &Value, path: &str, _ctx: &mut Ctx) -> P<Vec<(String, Mesh, Mat4)>> {
    let o = Obj::new(v, path, &["type", "path"])?;
    let file: String = o.req("path")?;
    Err(problem(
        path,
        format!("cannot load {file:?}: volshadow was built without the `gltf` feature"),
    ))
}

fn object(v: &Value, path: &str, i: usize, ctx: &mut Ctx, out: &mut Vec<SceneObject>) -> P<()> {
    let o = Obj::new(
        v,
        path,
        &["name", "shape", "transform", "casts_shadow", "albedo"],
    )?;
    let name: Option<String> = o.opt("name")?;
    let transform = match o.value("transform") {
        None => Mat4::IDENTITY,
        Some(t) => transform(t, &o.field("transform"))?,
    };
    let casts_shadow: bool = o.or("casts_shadow", true)?;
    let albedo = match o.value("albedo") {
        None => Vec3::splat(0.8),
        Some(a) => {
            let field = o.field("albedo");
            let a = non_negative(a, &field)?;
            ensure(a.max_element() <= 1.0, &field, || {
                format!("must be in [0, 1], got {a}")
            })?;
            a
        }
    };
    let (kind, shape) = shape(o.req_value("shape")?, &o.field("shape"), ctx)?;
    let name = name.unwrap_or_else(|| format!("{kind}_{i}"));
    match shape {
        Shape::One(mesh) => out.push({
            ctx.add(Limit::Instances, 1, path)?;
            SceneObject {
                name,
                mesh,
                transform,
                casts_shadow,
                albedo,
            }
        }),
        Shape::Many(meshes) => {
            for (mesh_name, mesh, node) in meshes {
                let composed = transform * node;
                check_transform(composed, &o.field("shape"))?;
                out.push(SceneObject {
                    name: format!("{name}/{mesh_name}"),
                    mesh,
                    transform: composed,
                    casts_shadow,
                    albedo,
                });
            }
        }
    }
    Ok(())
}

fn method(v: &Value, path: &str) -> P<Method> {
    const KINDS: [&str; 5] = ["reference", "hybrid", "exact", "brute_force", "textbook"];
    let defaults = |kind: &str| match kind {
        "reference" => Method::Reference,
        "brute_force" => Method::BruteForce {
            steps: 64,
            bisections: 0,
            scale: Scale::Full,
        },
        "textbook" => Method::Textbook {
            steps: 64,
            scale: Scale::Full,
        },
        "hybrid" => Method::hybrid_default(),
        _ => Method::exact_default(),
    };
    if let Some(s) = v.as_str() {
        ensure(KINDS.contains(&s), path, || {
            format!(
                "unknown method {s:?}; expected one of: {}",
                KINDS.join(", ")
            )
        })?;
        return Ok(defaults(s));
    }
    if !v.is_object() {
        return Err(expected(
            path,
            "a method name (reference, hybrid, exact, brute_force, textbook) or an object with \"type\"",
            v,
        ));
    }
    let kind = tag(v, path, "method", &KINDS)?;
    let o = match kind {
        "reference" => {
            Obj::new(v, path, &["type"])?;
            return Ok(Method::Reference);
        }
        "brute_force" => Obj::new(v, path, &["type", "steps", "bisections", "scale"])?,
        "textbook" => Obj::new(v, path, &["type", "steps", "scale"])?,
        "exact" => Obj::new(
            v,
            path,
            &[
                "type",
                "steps",
                "bisections",
                "scale",
                "upsample",
                "texture_steps",
                "crossings",
            ],
        )?,
        _ => Obj::new(
            v,
            path,
            &[
                "type",
                "steps",
                "bisections",
                "scale",
                "upsample",
                "texture_steps",
            ],
        )?,
    };
    let steps = count(&o, "steps", 64, 1, 4096)?;
    let bisections = count(&o, "bisections", 0, 0, 16)?;
    let divisor: u32 = o.or("scale", 1)?;
    let scale = Scale::from_divisor(divisor).map_err(|_| {
        problem(
            &o.field("scale"),
            format!("must be 1, 2 or 4 (scattering at 1/scale of the output size), got {divisor}"),
        )
    })?;
    if kind == "brute_force" {
        return Ok(Method::BruteForce {
            steps,
            bisections,
            scale,
        });
    }
    if kind == "textbook" {
        return Ok(Method::Textbook { steps, scale });
    }
    let upsample = match o.value("upsample") {
        None => UpsampleFilter::default(),
        Some(u) => upsample(u, &o.field("upsample"))?,
    };
    let texture_steps = count(&o, "texture_steps", 32, 1, 4096)?;
    if kind == "exact" {
        return Ok(Method::Exact {
            steps,
            scale,
            upsample,
            bisections,
            texture_steps,
            crossings: count(
                &o,
                "crossings",
                crate::nodes::DEFAULT_CROSSINGS,
                1,
                crate::nodes::MAX_CROSSINGS_PER_PIXEL,
            )?,
        });
    }
    Ok(Method::Hybrid {
        steps,
        scale,
        upsample,
        bisections,
        texture_steps,
    })
}

fn upsample(v: &Value, path: &str) -> P<UpsampleFilter> {
    if let Some(s) = v.as_str() {
        return match s {
            "bilinear" => Ok(UpsampleFilter::Bilinear),
            "depth_aware_3x3" => Ok(UpsampleFilter::DepthAware3x3),
            other => Err(problem(
                path,
                format!(
                    "unknown upsample filter {other:?}; expected \"bilinear\", \"depth_aware_3x3\" or {{\"separable\": {{...}}}}"
                ),
            )),
        };
    }
    let (_, value, field) = single_key(v, path, &["separable"])?;
    let o = Obj::new(value, &field, &["taps", "sigma_spatial", "sigma_depth"])?;
    let taps: u32 = o.req("taps")?;
    ensure(
        (3..=31).contains(&taps) && taps % 2 == 1,
        &o.field("taps"),
        || format!("must be odd and in 3..=31, got {taps}"),
    )?;
    let sigma_spatial: f32 = o.req("sigma_spatial")?;
    ensure(sigma_spatial > 0.0, &o.field("sigma_spatial"), || {
        format!("must be > 0, got {sigma_spatial}")
    })?;
    let sigma_depth: f32 = o.req("sigma_depth")?;
    ensure(sigma_depth > 0.0, &o.field("sigma_depth"), || {
        format!("must be > 0, got {sigma_depth}")
    })?;
    let filter = UpsampleFilter::Separable {
        taps,
        sigma_spatial,
        sigma_depth,
    };
    filter.validate().map_err(from_error(path))?;
    Ok(filter)
}
