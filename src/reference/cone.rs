//! The emission cone of a spot light, in f64, and the exact points where a ray crosses it.

use glam::DVec3;

use crate::scene::SpotLight;

/// Distance from the apex, relative to the eye's distance to it, within which a ray is taken to
/// pass through the apex: a few ulps, the rounding of `e − P` itself.
const APEX_TOLERANCE: f64 = 16.0 * f64::EPSILON;

/// The cone of a [`SpotLight`]: a point `X` is inside iff `a·(X − P) ≥ c·|X − P|`, with the
/// apex `P = position()`, the axis `a = direction()` and `c = cos_half_angle()`, each the
/// light's f32 value converted to f64 exactly, with no renormalisation: the test is exactly the
/// one [`SpotLight::cos_half_angle`] documents. The apex itself counts as inside.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Cone {
    apex: DVec3,
    axis: DVec3,
    cos_half: f64,
}

impl Cone {
    pub(crate) fn new(light: &SpotLight) -> Self {
        Self {
            apex: light.position().as_dvec3(),
            axis: light.direction().as_dvec3(),
            cos_half: f64::from(light.cos_half_angle()),
        }
    }

    /// The apex (the light's position).
    pub(crate) fn apex(&self) -> DVec3 {
        self.apex
    }

    /// Whether `x` lies inside the cone (boundary included).
    pub(crate) fn contains(&self, x: DVec3) -> bool {
        let w = x - self.apex;
        self.axis.dot(w) >= self.cos_half * w.length()
    }

    /// Ray distances where `e + x·v` (`v` unit) can enter or leave the cone, appended to `out`
    /// (any sign; the caller keeps those in its range).
    ///
    /// With `w(x) = e − P + x·v`, the surface of the double cone is the zero set of the
    /// quadratic `f(x) = (a·w)² − c²·|w|² = A·x² + 2·B·x + C`, and `g(x) = a·w − c·|w|`, whose
    /// sign is membership, can only change sign where `f` vanishes. So the candidates are the
    /// real roots of `f` (from both nappes: the caller's midpoint test keeps only the nappe in
    /// front of the light, `a·w ≥ 0`), taken by the cancellation-free formula
    /// `q = −(B + sign(B)·√(B² − A·C))`, `x = q/A` and `x = C/q` — which also gives the single
    /// root `−C/(2B)` of a ray parallel to a generator (`A = 0`). The vertex `−B/A` of the
    /// parabola is added too, harmless where it is not needed: it is the touching point of a
    /// tangent ray, whose discriminant rounding may make slightly negative.
    ///
    /// A ray through the apex `P` (`f = A·(x − x_P)²`, a double root; a ray on the cone's
    /// surface is one, with `f ≡ 0`) gives only `x_P`, the closest approach to the apex: a ray
    /// that passes within `APEX_TOLERANCE·|e − P|` of it (the rounding of `e − P` itself) is
    /// taken to pass through it. Everything is computed in units of `|e − P|`, so no
    /// coefficient overflows.
    pub(crate) fn candidates(&self, e: DVec3, v: DVec3, out: &mut Vec<f64>) {
        let w0 = e - self.apex;
        let scale = w0.length();
        let scale = if scale > 0.0 && scale.is_finite() {
            scale
        } else {
            1.0
        };
        let w0 = w0 / scale;
        let mut push = |x: f64| {
            let x = x * scale;
            if x.is_finite() {
                out.push(x);
            }
        };
        // A ray through the apex (to rounding): f = A·(x − x_P)², so the apex x_P is the only
        // point where membership can change. Returning it alone keeps the near-apex roots that
        // rounding scatters within a few ulps of it from making slivers the midpoint test
        // cannot decide reliably.
        if v.cross(w0).length() <= APEX_TOLERANCE {
            push(-v.dot(w0));
            return;
        }
        let c2 = self.cos_half * self.cos_half;
        let (av, aw) = (self.axis.dot(v), self.axis.dot(w0));
        let a = av * av - c2;
        let b = aw * av - c2 * v.dot(w0);
        let c = aw * aw - c2 * w0.length_squared();
        if a != 0.0 {
            push(-b / a);
        }
        let disc = b * b - a * c;
        if disc >= 0.0 {
            let q = -(b + disc.sqrt().copysign(b));
            if q != 0.0 {
                if a != 0.0 {
                    push(q / a);
                }
                push(c / q);
            }
        }
    }
}
