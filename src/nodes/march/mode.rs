//! How the march integrates each ray: the method a caller asks for ([`MarchMethod`]) and the
//! mode it takes for one light's frame ([`MarchMode`]), given the shadow inputs the frame has
//! ([`ShadowForms`]).

use super::{MarchInputs, Shadows};

/// How the march integrates each pixel's ray for one light this frame: the form its [`MarchMethod`]
/// takes given the shadow inputs the frame has, and the shader's `MODE` pipeline constant. The
/// planner picks it with [`MarchMode::choose`]
/// ([`LightPlan::march`](crate::plan::LightPlan::march)); a caller wiring the nodes by hand calls
/// `choose` too, and [`MarchNode::prepare`](crate::nodes::Node::prepare) checks that its inputs
/// carry what the mode reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MarchMode {
    /// No occluders: the closed-form airlight, one table lookup per pixel.
    Analytic = 0,
    /// Closed form outside the shadow volumes' extents (for a light with a radius, outside the
    /// penumbra cones of the soft-shadow grid), marched between them.
    Hybrid = 1,
    /// Marched over the whole ray.
    BruteForce = 2,
    /// Closed form between the crossings of each pixel's list.
    Exact = 3,
    /// The textbook Riemann sum over the whole ray.
    Textbook = 4,
}

/// Which shadow inputs a light's march has this frame (see [`MarchMode::choose`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ShadowForms {
    /// The shadow volumes' extents ([`Shadows::extents`]).
    pub extents: bool,
    /// The extents carry crossing lists.
    pub crossings: bool,
    /// A soft-shadow grid ([`Shadows::soft`]).
    pub soft_grid: bool,
}

impl ShadowForms {
    /// The forms `shadows` has.
    pub fn of(shadows: &Shadows<'_>) -> Self {
        Self {
            extents: shadows.extents.is_some(),
            crossings: shadows.extents.is_some_and(|e| e.crossings.is_some()),
            soft_grid: shadows.soft.is_some(),
        }
    }
}

impl MarchMode {
    /// The mode `method` takes for a light (`soft`: with a radius) whose shadows have `shadows`
    /// (`None`: no occluders): the one rule, read by the planner and by
    /// [`Cache::warm_up`](crate::nodes::Cache::warm_up). Without occluders the airlight is analytic
    /// (the textbook march still marches). A light with a radius and a soft-shadow grid is marched
    /// inside its penumbra cones (the extents bound the hard shadow only); otherwise the hybrid
    /// needs extents, the exact method extents with crossing lists, and what lacks them is marched
    /// over the whole ray.
    pub fn choose(method: MarchMethod, soft: bool, shadows: Option<ShadowForms>) -> MarchMode {
        use MarchMethod as M;
        match (method, shadows) {
            (M::Textbook, _) => MarchMode::Textbook,
            (_, None) => MarchMode::Analytic,
            (M::Exact | M::Hybrid, Some(s)) if soft && s.soft_grid => MarchMode::Hybrid,
            (M::Hybrid, Some(s)) if s.extents && !s.crossings => MarchMode::Hybrid,
            (M::Exact, Some(s)) if s.extents && s.crossings => MarchMode::Exact,
            _ => MarchMode::BruteForce,
        }
    }

    /// What this mode reads that `inputs` lack, if anything.
    pub(super) fn missing(self, inputs: &MarchInputs<'_>) -> Option<&'static str> {
        let forms = inputs.shadows.as_ref().map(ShadowForms::of);
        let soft = inputs.light.radius() > 0.0;
        match (self, forms) {
            (MarchMode::Analytic | MarchMode::Textbook, _) => None,
            (_, None) => Some("shadows"),
            (MarchMode::BruteForce, Some(_)) => None,
            (MarchMode::Hybrid, Some(f)) if (soft && f.soft_grid) || f.extents => None,
            (MarchMode::Hybrid, Some(_)) => {
                Some("shadows.extents (or, for a light with a radius, shadows.soft)")
            }
            (MarchMode::Exact, Some(f)) if f.crossings => None,
            (MarchMode::Exact, Some(_)) => Some("shadows.extents with crossing lists"),
        }
    }
}

impl std::fmt::Display for MarchMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            MarchMode::Analytic => "analytic",
            MarchMode::Hybrid => "hybrid",
            MarchMode::BruteForce => "brute force",
            MarchMode::Exact => "exact",
            MarchMode::Textbook => "textbook march",
        })
    }
}

/// How the shadowed part of each ray is integrated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum MarchMethod {
    /// Every shadow-volume face the ray crosses in front of the surface is recorded (up to
    /// [`MarchSettings::crossings`](crate::nodes::MarchSettings::crossings) per pixel); between
    /// consecutive crossings visibility is constant, so each interval is integrated in closed form
    /// (`T(s₁) − T(s₀)`) times its visibility (Biri, Arquès & Michelin 2006: exact integration
    /// between sorted shadow planes). Boundaries come from geometry, and so does visibility: an
    /// interval is lit where no closed volume is around it (counted from the far end); the shadow
    /// map decides only where a face of an open or non-manifold mesh crosses the pixel. A pixel
    /// whose list overflows is marched, as the hybrid does, between its nearest and farthest
    /// crossing. The default.
    #[default]
    Exact,
    /// Analytic outside the shadow-volume extents, marched between them (Wyman & Ramsey 2008).
    Hybrid,
    /// Marched over the whole ray, adding the closed-form integral between steps and
    /// sampling only the visibility: a strong baseline.
    BruteForce,
    /// The textbook march: a Riemann sum of the in-scattering integrand
    /// `σs·p·I·e^{−σt(d+x)}/d²·V·Δx` at steps uniform in distance, up to the surface or to
    /// where the transmittance from the eye falls below 1e-4 (as most engines' volumetric fog
    /// does). Only a baseline for the error-against-time report.
    Textbook,
}

impl std::fmt::Display for MarchMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            MarchMethod::Exact => "exact",
            MarchMethod::Hybrid => "hybrid",
            MarchMethod::BruteForce => "brute force",
            MarchMethod::Textbook => "textbook march",
        })
    }
}
