//! Lights.

use glam::Vec3;

use crate::error::{finite, non_negative, Error, Result};

/// A light's intensity (or a sun's irradiance): finite, non-negative, non-zero in some channel
/// and at most [`Light::MAX_INTENSITY`] in each.
fn emission(field: &'static str, v: Vec3) -> Result<()> {
    non_negative(field, &v.to_array())?;
    if v.max_element() <= 0.0 {
        return Err(Error::ZeroIntensity { field });
    }
    if v.max_element() > Light::MAX_INTENSITY {
        return Err(Error::InvalidSetting {
            field,
            problem: format!(
                "{} is above Light::MAX_INTENSITY = {:e} (f32's largest over 16): the passes' \
                 f32 products would overflow; scale the scene's lights and exposure down",
                v.max_element(),
                Light::MAX_INTENSITY
            ),
        });
    }
    Ok(())
}

/// An isotropic point light: radiant intensity `intensity` (RGB, per steradian) at `position`.
///
/// # Radius (soft shadows)
///
/// A light may have a [`radius`](Self::radius) (0 by default: a point, hard shadows). It is then
/// a sphere of that radius around `position`. At a point `X` of the medium, its visibility is
/// the fraction of the light's disc, as seen from `X`, that no occluder hides (measured as the
/// fraction of the solid angle of the cone from `X` tangent to the light); the in-scattered
/// integrand is the point light's (same `intensity`, distance and scattering angle measured
/// to the centre) times that fraction. This is an approximation for a radius much smaller than
/// the distances to the light; a point inside the sphere sees all of it. See
/// [`reference::visible_fraction`](crate::reference::visible_fraction).
///
/// Used in the [crate-level example](crate#example).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLight {
    position: Vec3,
    intensity: Vec3,
    radius: f32,
}

impl PointLight {
    /// A point light. The position must be finite; the intensity finite, non-negative and
    /// non-zero in at least one channel.
    ///
    /// Used in the [crate-level example](crate#example).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for a non-finite position or intensity, [`Error::Negative`] for a negative
    /// intensity channel, [`Error::ZeroIntensity`] when every channel is zero,
    /// [`Error::InvalidSetting`] for a channel above [`Light::MAX_INTENSITY`].
    pub fn new(position: Vec3, intensity: Vec3) -> Result<Self> {
        finite("point_light.position", &position.to_array())?;
        emission("point_light.intensity", intensity)?;
        Ok(Self {
            position,
            intensity,
            radius: 0.0,
        })
    }
    /// The same light as a sphere of `radius` (world units; 0, the default, is a point and
    /// gives hard shadows). See [Radius](Self#radius-soft-shadows); the march node documents
    /// how the GPU estimates the visible fraction
    /// ([`nodes::march`](crate::nodes::MarchNode#soft-shadows)).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for a non-finite radius, [`Error::Negative`] for a negative one.
    pub fn with_radius(self, radius: f32) -> Result<Self> {
        let radius = checked_radius("point_light.radius", radius)?;
        Ok(Self { radius, ..self })
    }
    /// World-space position.
    pub fn position(&self) -> Vec3 {
        self.position
    }
    /// Radiant intensity, RGB.
    pub fn intensity(&self) -> Vec3 {
        self.intensity
    }
    /// Radius of the light's sphere (0: a point).
    pub fn radius(&self) -> f32 {
        self.radius
    }
}

/// `radius` if finite and ≥ 0, with `-0.0` read as `0.0`.
fn checked_radius(field: &'static str, radius: f32) -> Result<f32> {
    finite(field, &[radius])?;
    non_negative(field, &[radius])?;
    Ok(if radius == 0.0 { 0.0 } else { radius })
}

/// A spot light: a point light whose emission is limited to a cone around `direction`, with a
/// hard edge at half the apex angle `cone_angle`. Its shadows come from a 2D shadow map.
///
/// A spot light may have a [`radius`](Self::radius), with the same model as a
/// [`PointLight`'s](PointLight#radius-soft-shadows); the cone stays the one from `position`,
/// with its hard edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpotLight {
    position: Vec3,
    direction: Vec3,
    cos_half_angle: f32,
    cone_angle: f32,
    intensity: Vec3,
    radius: f32,
    texture_up: Option<Vec3>,
}

impl SpotLight {
    /// The widest apex angle [`new`](Self::new) accepts: 179°, in radians (`179 · π/180` in
    /// f32, which is what `179f32.to_radians()` gives).
    ///
    /// Why 179° and not up to 180°: the cone itself is rendered to f32 precision at any angle
    /// below 180° (the ray–cone crossings are solved without cancellation, so a cone of
    /// 179.999° is as exact as one of 60°), but its shadows come from one perspective shadow
    /// map around the axis. A perspective map's texel spans `2·tan(fov/2)/resolution` at its
    /// centre, which grows without bound as the field nears 180° (the projection is singular
    /// at 180°: `cot(fov/2)`, its scale, reaches 0, and every texel near the axis covers a
    /// wider and wider angle); at 179° a 1024² map's central texel already spans 12.8°. The
    /// map's field is therefore capped at 179°, and a cone wider than the map would keep a
    /// band around its plane that no texel covers, where an occluder casts no shadow
    /// (measured: a thin slab 0.04°–0.27° below the plane of a 179.9° cone was ignored
    /// entirely, p95 4.8% against the reference, the same as leaving it out). So the widest
    /// cone is the widest map: 179°, where every point of the cone is inside the map.
    pub const MAX_CONE_ANGLE: f32 = 179.0 * (std::f32::consts::PI / 180.0);

    /// A spot light at `position` pointing along `direction` (any non-zero length), with apex
    /// angle `cone_angle` in radians, above 0 and at most [`MAX_CONE_ANGLE`](Self::MAX_CONE_ANGLE)
    /// (179°: see there why), and radiant intensity `intensity` inside the cone (finite,
    /// non-negative, non-zero in some channel).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] (position, direction, cone angle or intensity), [`Error::Negative`]
    /// (intensity), [`Error::DegenerateDirection`] for a zero-length direction,
    /// [`Error::ConeAngleOutOfRange`] for an angle outside (0, `MAX_CONE_ANGLE`],
    /// [`Error::ZeroIntensity`] when every channel is zero, [`Error::InvalidSetting`] for a
    /// channel above [`Light::MAX_INTENSITY`].
    pub fn new(position: Vec3, direction: Vec3, cone_angle: f32, intensity: Vec3) -> Result<Self> {
        finite("spot_light.position", &position.to_array())?;
        finite("spot_light.direction", &direction.to_array())?;
        finite("spot_light.cone_angle", &[cone_angle])?;
        // A finite direction whose length overflows (or underflows) f32 is rescaled first, so
        // it normalises too: only a zero vector is degenerate.
        let len = direction.length();
        let unit = if len.is_finite() && len > 0.0 {
            direction / len
        } else {
            (direction / direction.abs().max_element()).normalize_or_zero()
        };
        if unit == Vec3::ZERO || !unit.is_finite() {
            return Err(Error::DegenerateDirection {
                field: "spot_light.direction",
            });
        }
        if !(cone_angle > 0.0 && cone_angle <= Self::MAX_CONE_ANGLE) {
            return Err(Error::ConeAngleOutOfRange {
                angle: cone_angle,
                max: Self::MAX_CONE_ANGLE,
            });
        }
        emission("spot_light.intensity", intensity)?;
        Ok(Self {
            position,
            direction: unit,
            cos_half_angle: (0.5 * cone_angle).cos(),
            cone_angle,
            intensity,
            radius: 0.0,
            texture_up: None,
        })
    }
    /// The same light with its [texture frame](Self::texture_frame)'s up hint `up` (any
    /// non-zero finite length, not along the cone's axis): the frame's `+y` is `up` made
    /// perpendicular to the axis, so a projected texture turns with the light about its axis
    /// (an engine's light transform: its up vector). Without one the hint is `+Y`, or `+X` when
    /// the axis is within ~25° of vertical.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for a non-finite `up`, [`Error::DegenerateDirection`] (field
    /// `spot_light.texture_up`) for one of zero length or within ~0.06° of the axis (the
    /// sine of their angle below 1e-3), about which the frame's turn is undefined.
    pub fn with_texture_up(self, up: Vec3) -> Result<Self> {
        finite("spot_light.texture_up", &up.to_array())?;
        let scaled = up / up.abs().max_element();
        let unit = scaled.normalize_or_zero();
        if up == Vec3::ZERO || unit == Vec3::ZERO || self.direction.cross(unit).length() < 1e-3 {
            return Err(Error::DegenerateDirection {
                field: "spot_light.texture_up",
            });
        }
        Ok(Self {
            texture_up: Some(unit),
            ..self
        })
    }
    /// The same light as a sphere of `radius` (world units; 0, the default, is a point and
    /// gives hard shadows). See [`PointLight`'s radius](PointLight#radius-soft-shadows).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for a non-finite radius, [`Error::Negative`] for a negative one.
    pub fn with_radius(self, radius: f32) -> Result<Self> {
        let radius = checked_radius("spot_light.radius", radius)?;
        Ok(Self { radius, ..self })
    }
    /// World-space position.
    pub fn position(&self) -> Vec3 {
        self.position
    }
    /// Unit direction of the cone's axis.
    pub fn direction(&self) -> Vec3 {
        self.direction
    }
    /// Apex angle of the cone, radians.
    pub fn cone_angle(&self) -> f32 {
        self.cone_angle
    }
    /// Cosine of half the apex angle: a point X is inside the cone when
    /// `direction · (X − position) ≥ cos_half_angle · |X − position|`.
    pub fn cos_half_angle(&self) -> f32 {
        self.cos_half_angle
    }
    /// Radiant intensity inside the cone, RGB.
    pub fn intensity(&self) -> Vec3 {
        self.intensity
    }
    /// Radius of the light's sphere (0: a point).
    pub fn radius(&self) -> f32 {
        self.radius
    }
    /// The texture frame's up hint given by [`with_texture_up`](Self::with_texture_up)
    /// (normalised), if any.
    pub fn texture_up(&self) -> Option<Vec3> {
        self.texture_up
    }
}

/// A directional light (the sun): parallel rays travelling along `direction`, delivering the
/// RGB irradiance `irradiance` (`E`, power per unit area perpendicular to the rays) everywhere.
///
/// The light is at infinity and `E` is the irradiance *arriving in the medium*: there is no
/// attenuation on the light path, so a point `X` that sees the light (the half-line from `X`
/// towards `−direction` meets no occluder) receives exactly `E`, and the in-scattered radiance
/// along a camera ray is `∫ V(x) · σs · p(cos θ) · E · exp(−σt·x) dx`, with the scattering angle
/// `θ` the same at every point of the ray. A caller that wants a fog layer of extinction `σt`
/// and thickness `T` between the light and the scene passes `E·exp(−σt·T)`.
///
/// Its shadows come from [cascaded](Self::with_cascades) orthographic shadow maps fitted to
/// what the camera sees within the [shadow distance](Self::with_shadow_distance) (see
/// [`ShadowMapNode`](crate::nodes::ShadowMapNode)); [`crate::reference`] integrates it with
/// exact visibility (`inscatter_directional` and friends).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionalLight {
    direction: Vec3,
    irradiance: Vec3,
    shadow_distance: Option<f32>,
    cascades: u32,
}

impl DirectionalLight {
    /// A directional light whose rays travel along `direction` (any non-zero finite length; it
    /// is normalised), with irradiance `irradiance` (finite, non-negative, non-zero in some
    /// channel).
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] (direction or irradiance), [`Error::Negative`] (irradiance),
    /// [`Error::DegenerateDirection`] for a direction that cannot be normalised,
    /// [`Error::ZeroIntensity`] when every channel of the irradiance is zero,
    /// [`Error::InvalidSetting`] for a channel above [`Light::MAX_INTENSITY`].
    pub fn new(direction: Vec3, irradiance: Vec3) -> Result<Self> {
        finite("directional_light.direction", &direction.to_array())?;
        // Rescaled first, so that tiny or huge finite vectors normalise too.
        let largest = direction.abs().max_element();
        let direction = (direction / largest).normalize_or_zero();
        if largest == 0.0 || direction == Vec3::ZERO {
            return Err(Error::DegenerateDirection {
                field: "directional_light.direction",
            });
        }
        emission("directional_light.irradiance", irradiance)?;
        Ok(Self {
            direction,
            irradiance,
            shadow_distance: None,
            cascades: Self::DEFAULT_CASCADES,
        })
    }

    /// The number of cascades a new light's shadow map has.
    pub const DEFAULT_CASCADES: u32 = 4;
    /// The most cascades a light's shadow map may have (the layers a shadow map's parameters
    /// hold, as a point light's six cube faces).
    pub const MAX_CASCADES: u32 = 6;

    /// The same light with its shadow map split into `cascades` maps
    /// (1..=[`MAX_CASCADES`](Self::MAX_CASCADES); default
    /// [`DEFAULT_CASCADES`](Self::DEFAULT_CASCADES)), each covering a range of view distance
    /// from the eye to the [shadow distance](Self::with_shadow_distance), nearer ranges
    /// shorter, each at the map's full resolution: near the camera, shadows as sharp as a map
    /// over a few metres makes them, however far the scene extends. Each cascade costs one
    /// render of the occluders that can shadow its range.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSetting`] naming `directional_light.cascades` for 0 or more than
    /// [`MAX_CASCADES`](Self::MAX_CASCADES).
    pub fn with_cascades(self, cascades: u32) -> Result<Self> {
        if !(1..=Self::MAX_CASCADES).contains(&cascades) {
            return Err(Error::InvalidSetting {
                field: "directional_light.cascades",
                problem: format!("must be 1 to {}, got {cascades}", Self::MAX_CASCADES),
            });
        }
        Ok(Self { cascades, ..self })
    }

    /// The number of cascades (see [`with_cascades`](Self::with_cascades)).
    pub fn cascades(&self) -> u32 {
        self.cascades
    }
    /// The same light whose shadow map covers what the camera sees up to view depth `distance`
    /// from the eye (world units, finite and positive). Without it, the map covers up to the
    /// farthest corner of the occluders' bounds, and [`VolumetricShadows`](crate::VolumetricShadows)
    /// stops it at the medium's [`shadow_reach`](crate::scene::Medium::shadow_reach) where that
    /// is nearer. Beyond the shadow distance, points outside
    /// every cascade count as lit (see [`ShadowMapNode`](crate::nodes::ShadowMapNode)). A
    /// shorter distance spends the map's texels on a smaller region: sharper shafts near the
    /// camera.
    ///
    /// # Errors
    ///
    /// [`Error::NonFinite`] for a non-finite distance, [`Error::InvalidSetting`] naming
    /// `directional_light.shadow_distance` for one that is not positive.
    pub fn with_shadow_distance(self, distance: f32) -> Result<Self> {
        finite("directional_light.shadow_distance", &[distance])?;
        if distance <= 0.0 {
            return Err(Error::InvalidSetting {
                field: "directional_light.shadow_distance",
                problem: format!("must be positive, got {distance}"),
            });
        }
        Ok(Self {
            shadow_distance: Some(distance),
            ..self
        })
    }
    /// The shadow distance set by [`with_shadow_distance`](Self::with_shadow_distance)
    /// (`None`: from the occluders' bounds).
    pub fn shadow_distance(&self) -> Option<f32> {
        self.shadow_distance
    }
    /// Unit direction of travel of the light (from the light into the scene).
    pub fn direction(&self) -> Vec3 {
        self.direction
    }
    /// Irradiance arriving in the medium, RGB.
    pub fn irradiance(&self) -> Vec3 {
        self.irradiance
    }
}

/// Any light the crate renders.
///
/// Used in the [crate-level example](crate#example).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Light {
    /// Omnidirectional; shadows from a cube shadow map.
    Point(PointLight),
    /// Cone-limited; shadows from a 2D shadow map.
    Spot(SpotLight),
    /// Parallel rays (the sun); shadows from an orthographic shadow map.
    Directional(DirectionalLight),
}

impl Light {
    /// The largest intensity (a directional light's irradiance) in any channel: f32's largest
    /// value over 16, about 2.1e37. The passes multiply a light's intensity by the medium's
    /// coefficients, the phase function and distances in f32 and clamp the result at 1e30, so
    /// that no infinity reaches an output; an intensity near f32's largest value (3.4e38)
    /// overflows in those products before the clamp (1e38 drew every pixel at the clamp).
    /// Below this bound the stiff cases fit: a medium of optical depth 100 dims a light by
    /// e^−100 ≈ 4e-44, below f32's normal range, unless the light is that much brighter.
    /// A light bright enough that its in-scatter passes 1e30 still draws the clamp there:
    /// radiance is linear in the lights, so scale such a scene's lights (and exposure) down.
    pub const MAX_INTENSITY: f32 = f32::MAX / 16.0;

    /// World-space position (`None` for a directional light, which is at infinity).
    pub fn position(&self) -> Option<Vec3> {
        match self {
            Light::Point(l) => Some(l.position()),
            Light::Spot(l) => Some(l.position()),
            Light::Directional(_) => None,
        }
    }
    /// Radiant intensity (inside the cone for a spot light), RGB; for a directional light its
    /// irradiance.
    pub fn intensity(&self) -> Vec3 {
        match self {
            Light::Point(l) => l.intensity(),
            Light::Spot(l) => l.intensity(),
            Light::Directional(l) => l.irradiance(),
        }
    }
    /// Radius of the light's sphere (0: a point; see [`PointLight::with_radius`]; 0 for a
    /// directional light).
    pub fn radius(&self) -> f32 {
        match self {
            Light::Point(l) => l.radius(),
            Light::Spot(l) => l.radius(),
            Light::Directional(_) => 0.0,
        }
    }
}

impl From<PointLight> for Light {
    fn from(l: PointLight) -> Self {
        Light::Point(l)
    }
}
impl From<SpotLight> for Light {
    fn from(l: SpotLight) -> Self {
        Light::Spot(l)
    }
}
impl From<DirectionalLight> for Light {
    fn from(l: DirectionalLight) -> Self {
        Light::Directional(l)
    }
}
impl From<&DirectionalLight> for Light {
    fn from(l: &DirectionalLight) -> Self {
        Light::Directional(*l)
    }
}
impl From<&PointLight> for Light {
    fn from(l: &PointLight) -> Self {
        Light::Point(*l)
    }
}
impl From<&SpotLight> for Light {
    fn from(l: &SpotLight) -> Self {
        Light::Spot(*l)
    }
}
impl From<&Light> for Light {
    fn from(l: &Light) -> Self {
        *l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Census item 9: an intensity of 1e38 was accepted and every pixel drew the 1e30 clamp.
    /// Each kind of light accepts `MAX_INTENSITY` (2.1e37; the stiff tests' lights reach 1e37)
    /// and refuses 1e38 and the next f32 above the bound, naming its field and the bound.
    #[test]
    fn an_intensity_beyond_the_f32_range_is_an_error() {
        let at = |v: f32| Vec3::new(0.5, v, 1.0);
        let kinds = |v: f32| {
            [
                (
                    "point_light.intensity",
                    PointLight::new(Vec3::ZERO, at(v)).map(|_| ()),
                ),
                (
                    "spot_light.intensity",
                    SpotLight::new(Vec3::ZERO, Vec3::NEG_Y, 1.0, at(v)).map(|_| ()),
                ),
                (
                    "directional_light.irradiance",
                    DirectionalLight::new(Vec3::NEG_Y, at(v)).map(|_| ()),
                ),
            ]
        };
        for v in [1.0, 1e37, Light::MAX_INTENSITY] {
            for (field, r) in kinds(v) {
                assert!(r.is_ok(), "{field} {v:e}: {r:?}");
            }
        }
        let above = f32::from_bits(Light::MAX_INTENSITY.to_bits() + 1);
        for v in [1e38, above, f32::MAX] {
            for (field, r) in kinds(v) {
                match r {
                    Err(Error::InvalidSetting { field: f, problem }) => {
                        assert_eq!(f, field);
                        assert!(problem.contains("MAX_INTENSITY"), "{problem}");
                    }
                    other => panic!("{field} {v:e}: {other:?}"),
                }
            }
        }
    }

    /// A finite direction whose length overflows f32 (`[1e38; 3]`: its length is 1.7e38 · √3,
    /// beyond f32) or underflows it normalises, for spot and directional lights alike (the
    /// spot called it "zero length"); only zero is degenerate.
    #[test]
    fn huge_and_tiny_finite_directions_normalise() {
        for d in [
            Vec3::splat(1e38),
            Vec3::new(-3e38, 0.0, 3e38),
            Vec3::splat(1e-40),
        ] {
            let spot = SpotLight::new(Vec3::ZERO, d, 1.0, Vec3::ONE).unwrap();
            let sun = DirectionalLight::new(d, Vec3::ONE).unwrap();
            let want = (d.as_dvec3() / d.as_dvec3().length()).as_vec3();
            assert!(
                spot.direction().abs_diff_eq(want, 1e-6),
                "{d}: {}",
                spot.direction()
            );
            assert!(
                sun.direction().abs_diff_eq(want, 1e-6),
                "{d}: {}",
                sun.direction()
            );
        }
        assert!(matches!(
            SpotLight::new(Vec3::ZERO, Vec3::ZERO, 1.0, Vec3::ONE),
            Err(Error::DegenerateDirection { .. })
        ));
    }
}
