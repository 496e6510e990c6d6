//! Building the scene types from a parsed scene file ([`super::spec`]): ranges and cross-field
//! rules, with a field path on every error.

use std::path::{Path, PathBuf};

use glam::camera::rh::{proj::directx, view::look_at_mat4};
use glam::{Mat4, Vec2, Vec3};

use super::spec::{self, join, Flag, Floats, Int, Num, Rgb, Tagged, U32};
use super::{stained_glass, Method, SceneDescription, SceneLight, SceneObject};
use crate::error::Error;
use crate::load::{Budget, Limit};
use crate::nodes::{MarchSettings, Scale, UpsampleFilter};
use crate::scene::{
    shapes, Camera, DirectionalLight, Light, LightTexture, Medium, Mesh, PhaseFunction, PointLight,
    SpotLight,
};

/// A problem with one field of the file, before the file path is attached.
#[derive(Debug)]
pub(super) struct Problem {
    pub field: String,
    pub problem: String,
    /// An error reported as it is rather than as an [`Error::SceneFile`]: a path that leads
    /// outside the folder, a file that is not regular, a bound of the load passed.
    pub error: Option<Box<Error>>,
}

/// Result of building part of a scene.
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

/// Checks a condition, or fails with `message` at `path`.
fn ensure(ok: bool, path: &str, message: impl FnOnce() -> String) -> P<()> {
    if ok {
        Ok(())
    } else {
        Err(problem(path, message()))
    }
}

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
fn from_error(path: &str) -> impl FnOnce(Error) -> Problem + '_ {
    move |e| problem(path, e.to_string())
}

/// A settings error from a `validate`, reported at `path` and the field it names after
/// `prefix` (`march.steps` at `method` is `method.steps`).
fn setting<'a>(prefix: &'a str, path: &'a str) -> impl FnOnce(Error) -> Problem + 'a {
    move |e| match &e {
        Error::InvalidSetting { field, problem: p } => match field.strip_prefix(prefix) {
            Some(key) => problem(&join(path, key), p.clone()),
            None => problem(path, e.to_string()),
        },
        _ => problem(path, e.to_string()),
    }
}

/// A crate error from loading a file or counting a total: the errors of [`crate::load`] are
/// kept as they are, others are reported at `path`.
fn from_load_error(path: &str) -> impl FnOnce(Error) -> Problem + '_ {
    move |e| match e {
        Error::PathOutsideFolder { .. }
        | Error::NotRegularFile { .. }
        | Error::LimitExceeded { .. } => Problem {
            field: path.to_owned(),
            problem: e.to_string(),
            error: Some(Box::new(e)),
        },
        e => problem(path, e.to_string()),
    }
}

/// What building a scene needs besides the file: where its files are and the load's totals.
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
    /// Only image files are read through it (glTF files are confined and read by the loader).
    #[cfg_attr(not(feature = "image"), allow(dead_code))]
    fn read(&mut self, named: &str, path: &str) -> P<(PathBuf, Vec<u8>)> {
        let folder = self
            .folder
            .as_ref()
            .map_err(|e| problem(path, format!("cannot resolve {named:?}: {e}")))?;
        crate::load::read_named(&mut self.budget, folder, Path::new(named), self.file, path)
            .map_err(from_load_error(path))
    }
}

/// A point: each coordinate within ±[`MAX_COORD`].
fn point(Floats(p): Floats<3>, path: &str) -> P<Vec3> {
    let p = Vec3::from_array(p);
    ensure(p.abs().max_element() <= MAX_COORD, path, || {
        format!("coordinates must be within ±{MAX_COORD:e}, got {p}")
    })?;
    Ok(p)
}

/// A length in [[`MIN_LENGTH`], [`MAX_COORD`]].
fn length(Num(x): Num, path: &str) -> P<f32> {
    ensure((MIN_LENGTH..=MAX_COORD).contains(&x), path, || {
        format!("must be in [{MIN_LENGTH:e}, {MAX_COORD:e}], got {x}")
    })?;
    Ok(x)
}

/// `N` lengths.
fn lengths<const N: usize>(Floats(v): Floats<N>, path: &str) -> P<[f32; N]> {
    for (i, x) in v.into_iter().enumerate() {
        length(Num(x), &format!("{path}[{i}]"))?;
    }
    Ok(v)
}

/// An optional count in `min..=max`, with a default.
fn count(n: Option<U32>, path: &str, default: u32, min: u32, max: u32) -> P<u32> {
    let n = n.map_or(default, |U32(n)| n);
    ensure((min..=max).contains(&n), path, || {
        format!("must be in {min}..={max}, got {n}")
    })?;
    Ok(n)
}

/// RGB, each channel >= 0.
fn non_negative(Rgb(c): Rgb, path: &str) -> P<Vec3> {
    ensure(c.min_element() >= 0.0, path, || {
        format!("must be >= 0, got {c}")
    })?;
    Ok(c)
}

/// A Henyey–Greenstein asymmetry in (−1, 1).
fn asymmetry(Num(g): Num, path: &str) -> P<f32> {
    ensure(g.abs() < 1.0, path, || {
        format!("the asymmetry g must be in (-1, 1), got {g}")
    })?;
    Ok(g)
}

/// The whole file.
pub(super) fn scene(s: spec::Scene, ctx: &mut Ctx) -> P<SceneDescription> {
    let size = match s.size {
        None => (512, 512),
        Some([U32(w), U32(h)]) => {
            for (i, n) in [w, h].into_iter().enumerate() {
                ensure((1..=MAX_SIZE).contains(&n), &format!("size[{i}]"), || {
                    format!("must be in 1..={MAX_SIZE}, got {n}")
                })?;
            }
            (w, h)
        }
    };
    let camera = camera(s.camera, "camera", size)?;
    ctx.add(Limit::Lights, s.lights.len() as u64, "lights")?;
    ensure(!s.lights.is_empty(), "lights", || {
        "must contain at least one light".to_owned()
    })?;
    let mut lights = Vec::with_capacity(s.lights.len());
    for (i, Tagged(l)) in s.lights.into_iter().enumerate() {
        lights.push(light(l, &format!("lights[{i}]"), ctx)?);
    }
    let medium = medium(s.medium, "medium")?;
    let specs: Vec<spec::Object> = s.objects.into_iter().flatten().collect();
    // The triangles every procedural shape declares, counted before any shape is built: a
    // small file asking for more than the bound is refused at once, naming its total (20
    // spheres of 2M triangles were refused only after two were built, 12.5 s and 409 MB).
    // A glTF file's triangles are counted as it is read (from its accessors, before they
    // are).
    let declared = specs
        .iter()
        .map(|o| declared_triangles(&o.shape.0))
        .fold(0, u64::saturating_add);
    ctx.check(Limit::Triangles, declared, "objects")?;
    let mut objects = Vec::new();
    for (i, o) in specs.into_iter().enumerate() {
        object(o, &format!("objects[{i}]"), i, ctx, &mut objects)?;
    }
    Ok(SceneDescription {
        name: s.name,
        description: s.description,
        size,
        camera,
        lights,
        medium,
        objects,
        method: method(s.method, "method")?,
    })
}

fn camera(c: spec::Camera, path: &str, (width, height): (u32, u32)) -> P<Camera> {
    let at = |key| join(path, key);
    let eye = point(c.eye, &at("eye"))?;
    let target = point(c.target, &at("target"))?;
    let up = c.up.map_or(Vec3::Y, |Floats(u)| Vec3::from_array(u));
    let Num(fov) = c.fov_y_degrees;
    ensure(fov > 0.0 && fov < 180.0, &at("fov_y_degrees"), || {
        format!("must be in (0, 180), got {fov}")
    })?;
    let near = length(c.near, &at("near"))?;
    let far = c.far.map(|Num(f)| f);
    if let Some(far) = far {
        ensure(far > near && far <= MAX_COORD * 1e3, &at("far"), || {
            format!(
                "must be greater than near ({near}) and at most {:e}, or null for an infinite far plane; got {far}",
                MAX_COORD * 1e3
            )
        })?;
    }
    let reversed = c.reversed_z.is_some_and(|Flag(b)| b);

    let forward = target - eye;
    ensure(forward.length() > 0.0, &at("target"), || {
        "must differ from eye".to_owned()
    })?;
    let up = up.normalize_or_zero();
    ensure(up != Vec3::ZERO, &at("up"), || {
        "must be non-zero".to_owned()
    })?;
    ensure(
        forward.normalize().cross(up).length() > 1e-3,
        &at("up"),
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

fn intensity(i: Rgb, path: &str) -> P<Vec3> {
    let i = non_negative(i, path)?;
    ensure(i.max_element() > 0.0, path, || {
        "is zero in every channel: the light would contribute nothing".to_owned()
    })?;
    Ok(i)
}

/// A light's radius: finite and ≥ 0, 0 when left out (a point: hard shadows).
fn light_radius(r: Option<spec::Num>, path: &str) -> P<f32> {
    let r = r.map_or(0.0, |spec::Num(r)| r);
    ensure(r.is_finite() && r >= 0.0, path, || {
        format!("must be finite and at least 0, got {r}")
    })?;
    Ok(r)
}

fn light(l: spec::Light, path: &str, ctx: &mut Ctx) -> P<SceneLight> {
    let at = |key| join(path, key);
    match l {
        spec::Light::Point {
            position,
            intensity: i,
            radius: r,
        } => {
            let position = point(position, &at("position"))?;
            let i = intensity(i, &at("intensity"))?;
            let r = light_radius(r, &at("radius"))?;
            let light = PointLight::new(position, i)
                .and_then(|l| l.with_radius(r))
                .map_err(from_error(path))?;
            Ok(SceneLight {
                light: Light::Point(light),
                texture: None,
            })
        }
        spec::Light::Spot {
            position,
            direction: Floats(direction),
            cone_angle_degrees: Num(cone),
            intensity: i,
            texture: t,
            texture_up,
            radius: r,
        } => {
            let position = point(position, &at("position"))?;
            let direction = Vec3::from_array(direction);
            ensure(
                direction.length().is_finite() && direction.length() > 0.0,
                &at("direction"),
                || format!("must be a non-zero finite vector, got {direction}"),
            )?;
            // The widest cone is `SpotLight::MAX_CONE_ANGLE`, 179° (the widest shadow map).
            ensure(
                cone > 0.0 && cone <= 179.0,
                &at("cone_angle_degrees"),
                || {
                    format!("must be in (0, 179] (the widest field a spot's shadow map covers), got {cone}")
                },
            )?;
            let i = intensity(i, &at("intensity"))?;
            let texture = t.map(|t| texture(t, &at("texture"), ctx)).transpose()?;
            let r = light_radius(r, &at("radius"))?;
            let mut light = SpotLight::new(position, direction, cone.to_radians(), i)
                .and_then(|l| l.with_radius(r))
                .map_err(from_error(path))?;
            if let Some(Floats(up)) = texture_up {
                let up = Vec3::from_array(up);
                light = light.with_texture_up(up).map_err(|_| {
                    problem(
                        &at("texture_up"),
                        format!(
                            "must be a finite vector with a part across the direction, got {up}"
                        ),
                    )
                })?;
            }
            Ok(SceneLight {
                light: Light::Spot(light),
                texture,
            })
        }
        spec::Light::Directional {
            direction: Floats(direction),
            irradiance: e,
            shadow_distance,
        } => {
            let direction = Vec3::from_array(direction);
            ensure(
                direction.length().is_finite() && direction.length() > 0.0,
                &at("direction"),
                || format!("must be a non-zero finite vector, got {direction}"),
            )?;
            let e = intensity(e, &at("irradiance"))?;
            let mut light = DirectionalLight::new(direction, e).map_err(from_error(path))?;
            if let Some(Num(d)) = shadow_distance {
                ensure(d.is_finite() && d > 0.0, &at("shadow_distance"), || {
                    format!("must be a positive finite distance, got {d}")
                })?;
                light = light.with_shadow_distance(d).map_err(from_error(path))?;
            }
            Ok(SceneLight {
                light: Light::Directional(light),
                texture: None,
            })
        }
    }
}

/// A procedural texture's size and cell count, counted into the load's texels.
fn texture_size(U32(size): U32, U32(cells): U32, path: &str, ctx: &mut Ctx) -> P<(u32, u32)> {
    let at = |key| join(path, key);
    ensure((1..=MAX_TEXTURE).contains(&size), &at("size"), || {
        format!("must be in 1..={MAX_TEXTURE}, got {size}")
    })?;
    ensure((1..=size).contains(&cells), &at("cells"), || {
        format!("must be in 1..={size} (the texture size), got {cells}")
    })?;
    ctx.add(
        Limit::Texels,
        u64::from(size) * u64::from(size),
        &at("size"),
    )?;
    Ok((size, cells))
}

fn texture(t: spec::Texture, path: &str, ctx: &mut Ctx) -> P<LightTexture> {
    match t {
        spec::Texture::Checkerboard { size, cells, a, b } => {
            let path = &join(path, "checkerboard");
            let (size, cells) = texture_size(size, cells, path, ctx)?;
            let a = non_negative(a, &join(path, "a"))?;
            let b = non_negative(b, &join(path, "b"))?;
            LightTexture::checkerboard(size, cells, a, b).map_err(from_error(path))
        }
        spec::Texture::StainedGlass {
            size,
            cells,
            seed: Int(seed),
        } => {
            let path = &join(path, "stained_glass");
            let (size, cells) = texture_size(size, cells, path, ctx)?;
            stained_glass(size, cells, seed).map_err(from_error(path))
        }
        spec::Texture::File(file) => image_file(&file, &join(path, "file"), ctx),
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

fn medium(m: spec::Medium, path: &str) -> P<Medium> {
    let at = |key| join(path, key);
    let sigma_s = m
        .sigma_s
        .map(|v| non_negative(v, &at("sigma_s")))
        .transpose()?;
    let sigma_a = match m.sigma_a {
        None => Vec3::ZERO,
        Some(v) => non_negative(v, &at("sigma_a"))?,
    };
    let phase = match m.phase {
        None => PhaseFunction::Isotropic,
        Some(v) => phase(v, &at("phase"))?,
    };
    if let PhaseFunction::HoffmanPreetham { rayleigh, mie, g } = phase {
        ensure(sigma_s.is_none(), &at("sigma_s"), || {
            "must not be given with the hoffman_preetham phase, which sets sigma_s = rayleigh + mie"
                .to_owned()
        })?;
        return Medium::hoffman_preetham(rayleigh, mie, g, sigma_a)
            .map_err(from_error(&at("phase")));
    }
    let sigma_s = sigma_s.ok_or_else(|| {
        problem(
            &at("sigma_s"),
            "missing required field (unless the phase is hoffman_preetham)",
        )
    })?;
    Medium::new(sigma_s, sigma_a, phase).map_err(from_error(path))
}

fn phase(p: spec::Phase, path: &str) -> P<PhaseFunction> {
    Ok(match p {
        spec::Phase::Isotropic => PhaseFunction::Isotropic,
        spec::Phase::Rayleigh => PhaseFunction::Rayleigh,
        spec::Phase::MieHazy => PhaseFunction::MieHazy,
        spec::Phase::MieMurky => PhaseFunction::MieMurky,
        spec::Phase::HenyeyGreenstein(g) => PhaseFunction::HenyeyGreenstein {
            g: asymmetry(g, &join(path, "henyey_greenstein"))?,
        },
        spec::Phase::HoffmanPreetham { rayleigh, mie, g } => {
            let path = &join(path, "hoffman_preetham");
            let rayleigh = non_negative(rayleigh, &join(path, "rayleigh"))?;
            let mie = non_negative(mie, &join(path, "mie"))?;
            let g = asymmetry(g, &join(path, "g"))?;
            let sum = rayleigh + mie;
            ensure(sum.min_element() > 0.0, path, || {
                format!("rayleigh + mie must be > 0 in every channel, got {sum}")
            })?;
            PhaseFunction::HoffmanPreetham { rayleigh, mie, g }
        }
    })
}

fn transform(t: spec::Transform, path: &str) -> P<Mat4> {
    let at = |key| join(path, key);
    let m = if let Some(Floats(matrix)) = t.matrix {
        let given = [
            ("translate", t.translate.is_some()),
            ("rotate_degrees", t.rotate_degrees.is_some()),
            ("scale", t.scale.is_some()),
        ];
        if let Some((other, _)) = given.into_iter().find(|(_, given)| *given) {
            return Err(problem(&at(other), "cannot be combined with `matrix`"));
        }
        let m = Mat4::from_cols_array(&matrix);
        ensure(
            m.row(3) == glam::Vec4::new(0.0, 0.0, 0.0, 1.0),
            &at("matrix"),
            || {
                format!(
                    "must be affine (column-major; the last row must be 0, 0, 0, 1), got last row {}",
                    m.row(3)
                )
            },
        )?;
        ensure(
            m.w_axis.truncate().abs().max_element() <= MAX_COORD,
            &at("matrix"),
            || format!("its translation must be within ±{MAX_COORD:e}"),
        )?;
        m
    } else {
        let translate = match t.translate {
            Some(p) => point(p, &at("translate"))?,
            None => Vec3::ZERO,
        };
        let rotate = t.rotate_degrees.map_or(Vec3::ZERO, |Floats(r)| r.into());
        ensure(
            rotate.abs().max_element() <= 36_000.0,
            &at("rotate_degrees"),
            || format!("angles must be within ±36000 degrees, got {rotate}"),
        )?;
        let Rgb(scale) = t.scale.unwrap_or(Rgb(Vec3::ONE));
        ensure(
            scale.min_element() >= MIN_LENGTH && scale.max_element() <= MAX_COORD,
            &at("scale"),
            || {
                format!("must be in [{MIN_LENGTH:e}, {MAX_COORD:e}] (mirroring is not allowed), got {scale}")
            },
        )?;
        let r = rotate * (std::f32::consts::PI / 180.0);
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

/// An optional count as written, or `default`; a count outside `min..=max` (which the shape
/// itself reports) as `min`.
fn declared_count(n: Option<U32>, default: u32, min: u32, max: u32) -> u64 {
    let n = n.map_or(default, |U32(n)| n);
    u64::from(if (min..=max).contains(&n) { n } else { min })
}

/// The triangles the procedural shape `s` makes, from its counts as written (the sizes
/// [`shapes`] builds): what the scene's pre-count and each shape's own check before it is
/// built add up. A count out of its range counts as its least (the shape reports it); a glTF
/// file counts 0 here (its loader counts its triangles before reading them).
fn declared_triangles(s: &spec::Shape) -> u64 {
    use spec::Shape as S;
    match s {
        S::Sphere {
            segments, rings, ..
        } => {
            let segments = declared_count(*segments, 32, 3, MAX_SEGMENTS);
            let rings = declared_count(*rings, 16, 2, MAX_SEGMENTS);
            2 * segments * (rings - 1)
        }
        S::Box { .. } => 12,
        S::Plane { .. } => 2,
        S::Torus {
            major_segments,
            minor_segments,
            ..
        } => {
            let m = declared_count(*major_segments, 48, 3, MAX_SEGMENTS);
            let n = declared_count(*minor_segments, 16, 3, MAX_SEGMENTS);
            2 * m * n
        }
        S::Spring {
            turns: Num(turns),
            segments_per_turn,
            wire_segments,
            ..
        } => {
            let per_turn = declared_count(*segments_per_turn, 32, 3, 256);
            let wire_segments = declared_count(*wire_segments, 12, 3, 64);
            // (steps + 1) wire rings of `wire_segments` quads, and two end caps.
            let steps = (turns.clamp(0.01, 1000.0) * per_turn as f32).min(16384.0);
            let steps = (steps.ceil() as u64).max(1);
            2 * (steps + 1) * wire_segments
        }
        S::Cylinder { segments, .. } => 2 * declared_count(*segments, 32, 3, MAX_SEGMENTS),
        // 12 triangles per box: the posts and two rails.
        S::Fence { posts: U32(p), .. } => 12 * (declared_count(Some(U32(*p)), 1, 1, 1024) + 2),
        S::Gltf { .. } => 0,
    }
}

/// What a `shape` produces: one mesh, or (glTF) several with their own names and transforms.
enum Shape {
    One(Mesh),
    Many(Vec<(String, Mesh, Mat4)>),
}

fn shape(s: spec::Shape, path: &str, ctx: &mut Ctx) -> P<(&'static str, Shape)> {
    use spec::Shape as S;
    let at = |key| join(path, key);
    let declared = declared_triangles(&s);
    let (kind, mesh) = match s {
        S::Sphere {
            center,
            radius,
            segments,
            rings,
        } => {
            let radius = length(radius, &at("radius"))?;
            let segments = count(segments, &at("segments"), 32, 3, MAX_SEGMENTS)?;
            let rings = count(rings, &at("rings"), 16, 2, MAX_SEGMENTS)?;
            let center = point(center, &at("center"))?;
            ctx.check(Limit::Triangles, declared, path)?;
            ("sphere", shapes::uv_sphere(center, radius, segments, rings))
        }
        S::Box {
            center,
            half_extents,
        } => {
            let center = point(center, &at("center"))?;
            let half = lengths(half_extents, &at("half_extents"))?;
            ("box", shapes::cuboid(center, half.into()))
        }
        S::Plane { center, half_size } => {
            let center = point(center, &at("center"))?;
            let half = lengths(half_size, &at("half_size"))?;
            ("plane", shapes::plane(center, Vec2::from(half)))
        }
        S::Torus {
            center,
            major_radius,
            minor_radius,
            major_segments,
            minor_segments,
        } => {
            let center = point(center, &at("center"))?;
            let major = length(major_radius, &at("major_radius"))?;
            let minor = length(minor_radius, &at("minor_radius"))?;
            ensure(
                minor < major && minor >= 1e-4 * major,
                &at("minor_radius"),
                || {
                    format!(
                        "must be below major_radius ({major}) and at least 1e-4 of it, got {minor}"
                    )
                },
            )?;
            let m = count(major_segments, &at("major_segments"), 48, 3, MAX_SEGMENTS)?;
            let n = count(minor_segments, &at("minor_segments"), 16, 3, MAX_SEGMENTS)?;
            ctx.check(Limit::Triangles, declared, path)?;
            ("torus", shapes::torus(center, major, minor, m, n))
        }
        S::Spring {
            center,
            coil_radius,
            wire_radius,
            turns: Num(turns),
            height,
            segments_per_turn,
            wire_segments,
        } => {
            let center = point(center, &at("center"))?;
            let coil = length(coil_radius, &at("coil_radius"))?;
            let wire = length(wire_radius, &at("wire_radius"))?;
            ensure((0.01..=1000.0).contains(&turns), &at("turns"), || {
                format!("must be in [0.01, 1000], got {turns}")
            })?;
            let height = length(height, &at("height"))?;
            ensure(wire >= 1e-4 * coil.max(height), &at("wire_radius"), || {
                format!(
                    "must be at least 1e-4 of coil_radius and height ({}), got {wire}",
                    coil.max(height)
                )
            })?;
            let per_turn = count(segments_per_turn, &at("segments_per_turn"), 32, 3, 256)?;
            let wire_segments = count(wire_segments, &at("wire_segments"), 12, 3, 64)?;
            ensure(
                turns * per_turn as f32 <= 16384.0,
                &at("segments_per_turn"),
                || {
                    format!(
                        "turns × segments_per_turn must be at most 16384, got {}",
                        turns * per_turn as f32
                    )
                },
            )?;
            ctx.check(Limit::Triangles, declared, path)?;
            let mesh =
                shapes::helix_spring(center, coil, wire, turns, height, per_turn, wire_segments);
            ("spring", mesh)
        }
        S::Cylinder {
            center,
            radius,
            half_height,
            segments,
        } => {
            let center = point(center, &at("center"))?;
            let radius = length(radius, &at("radius"))?;
            let half_height = length(half_height, &at("half_height"))?;
            let segments = count(segments, &at("segments"), 32, 3, MAX_SEGMENTS)?;
            ctx.check(Limit::Triangles, declared, path)?;
            let mesh = shapes::cylinder_open(center, radius, half_height, segments);
            ("cylinder", mesh)
        }
        S::Fence {
            center,
            posts: U32(posts),
            spacing,
            post_half_extents,
            rail,
        } => {
            let center = match center {
                Some(c) => point(c, &at("center"))?,
                None => Vec3::ZERO,
            };
            ensure((1..=1024).contains(&posts), &at("posts"), || {
                format!("must be in 1..=1024, got {posts}")
            })?;
            let spacing = length(spacing, &at("spacing"))?;
            let half = lengths(post_half_extents, &at("post_half_extents"))?;
            let rail = rail.is_some_and(|Flag(b)| b);
            ctx.check(Limit::Triangles, declared, path)?;
            (
                "fence",
                shapes::fence(center, posts, spacing, half.into(), rail),
            )
        }
        S::Gltf { path: file } => {
            return gltf(&file, &at("path"), path, ctx).map(|m| ("gltf", Shape::Many(m)))
        }
    };
    let mesh = mesh.map_err(from_error(path))?;
    ctx.add(Limit::Triangles, mesh.triangle_count() as u64, path)?;
    Ok((kind, Shape::One(mesh)))
}

#[cfg(feature = "gltf")]
fn gltf(file: &str, field: &str, _shape: &str, ctx: &mut Ctx) -> P<Vec<(String, Mesh, Mat4)>> {
    let folder = ctx
        .folder
        .as_ref()
        .map_err(|e| problem(field, format!("cannot resolve {file:?}: {e}")))?;
    let allow = ctx.budget.options.allow_outside;
    let file = crate::load::confine(folder, Path::new(file), allow, ctx.file, field)
        .map_err(from_load_error(field))?;
    // Its triangles and placed meshes count into the scene's totals.
    let meshes =
        crate::gltf::load_budgeted(&file, &mut ctx.budget).map_err(from_load_error(field))?;
    ensure(!meshes.is_empty(), field, || {
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
fn gltf(file: &str, _field: &str, shape: &str, _ctx: &mut Ctx) -> P<Vec<(String, Mesh, Mat4)>> {
    Err(problem(
        shape,
        format!("cannot load {file:?}: volshadow was built without the `gltf` feature"),
    ))
}

fn object(
    o: spec::Object,
    path: &str,
    i: usize,
    ctx: &mut Ctx,
    out: &mut Vec<SceneObject>,
) -> P<()> {
    let at = |key| join(path, key);
    let transform = match o.transform {
        None => Mat4::IDENTITY,
        Some(t) => transform(t, &at("transform"))?,
    };
    let casts_shadow = o.casts_shadow.is_none_or(|Flag(b)| b);
    let albedo = match o.albedo {
        None => Vec3::splat(0.8),
        Some(a) => {
            let a = non_negative(a, &at("albedo"))?;
            ensure(a.max_element() <= 1.0, &at("albedo"), || {
                format!("must be in [0, 1], got {a}")
            })?;
            a
        }
    };
    let Tagged(s) = o.shape;
    let (kind, shape) = shape(s, &at("shape"), ctx)?;
    let name = o.name.unwrap_or_else(|| format!("{kind}_{i}"));
    match shape {
        Shape::One(mesh) => {
            ctx.add(Limit::Instances, 1, path)?;
            out.push(SceneObject {
                name,
                mesh,
                transform,
                casts_shadow,
                albedo,
            });
        }
        Shape::Many(meshes) => {
            for (mesh_name, mesh, node) in meshes {
                let composed = transform * node;
                check_transform(composed, &at("shape"))?;
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

/// The method, with [`MarchSettings`]'s defaults and checked by its `validate`.
fn method(m: Option<Tagged<spec::Method>>, path: &str) -> P<Method> {
    use spec::Method as M;
    let Some(Tagged(m)) = m else {
        return Ok(Method::default());
    };
    let d = MarchSettings::default();
    let or = |n: Option<U32>, default: u32| n.map_or(default, |U32(n)| n);
    let scale = |s: Option<U32>| {
        let divisor = or(s, 1);
        Scale::from_divisor(divisor).map_err(|_| {
            problem(
                &join(path, "scale"),
                format!(
                    "must be 1, 2 or 4 (scattering at 1/scale of the output size), got {divisor}"
                ),
            )
        })
    };
    let upsample = |u: Option<spec::Upsample>| upsample(u, &join(path, "upsample"));
    let method = match m {
        M::Reference {} => return Ok(Method::Reference),
        M::BruteForce {
            steps,
            bisections,
            scale: s,
        } => Method::BruteForce {
            steps: or(steps, d.steps),
            bisections: or(bisections, d.bisections),
            scale: scale(s)?,
        },
        M::Textbook { steps, scale: s } => Method::Textbook {
            steps: or(steps, d.steps),
            scale: scale(s)?,
        },
        M::Hybrid {
            steps,
            bisections,
            scale: s,
            upsample: u,
            texture_steps,
        } => Method::Hybrid {
            steps: or(steps, d.steps),
            scale: scale(s)?,
            upsample: upsample(u)?,
            bisections: or(bisections, d.bisections),
            texture_steps: or(texture_steps, d.texture_steps),
        },
        M::Exact {
            steps,
            bisections,
            scale: s,
            upsample: u,
            texture_steps,
            crossings,
        } => Method::Exact {
            steps: or(steps, d.steps),
            scale: scale(s)?,
            upsample: upsample(u)?,
            bisections: or(bisections, d.bisections),
            texture_steps: or(texture_steps, d.texture_steps),
            crossings: or(crossings, d.crossings),
        },
    };
    if let Some(settings) = method.march_settings() {
        settings.validate().map_err(setting("march.", path))?;
    }
    Ok(method)
}

fn upsample(u: Option<spec::Upsample>, path: &str) -> P<UpsampleFilter> {
    let filter = match u {
        None => UpsampleFilter::default(),
        Some(spec::Upsample::Bilinear) => UpsampleFilter::Bilinear,
        Some(spec::Upsample::DepthAware3x3) => UpsampleFilter::DepthAware3x3,
        Some(spec::Upsample::Separable {
            taps: U32(taps),
            sigma_spatial: Num(sigma_spatial),
            sigma_depth: Num(sigma_depth),
        }) => UpsampleFilter::Separable {
            taps,
            sigma_spatial,
            sigma_depth,
        },
    };
    filter
        .validate()
        .map_err(setting("upsample.", &join(path, "separable")))?;
    Ok(filter)
}
