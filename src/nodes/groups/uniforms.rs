//! GPU-side uniform structs (mirrors of the WGSL structs in `shaders/shared/prelude.wgsl`) and
//! their construction from the scene types.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::light::{LightUniform, Source};
use crate::scene::{Camera, Light, Medium, PhaseFunction};

/// WGSL `Airlight`, field by field (see there what each holds).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct AirlightUniform {
    pub light_pos: [f32; 3],
    pub distance: f32,
    pub eye: [f32; 3],
    pub pixel_radius: f32,
    pub intensity: [f32; 3],
    pub hg_g: f32,
    pub sigma_s: [f32; 3],
    pub table_along: u32,
    pub sigma_t: [f32; 3],
    pub table_across: u32,
    pub w_iso: [f32; 4],
    pub w_rayleigh: [f32; 4],
    pub w_hg: [f32; 4],
    pub w_hazy: [f32; 4],
    pub w_murky: [f32; 4],
}

/// Per-channel weights of the five phase lobes (iso, Rayleigh, HG, hazy, murky) and HG's g.
fn phase_lobes(phase: PhaseFunction) -> ([Vec3; 5], f32) {
    let z = Vec3::ZERO;
    let one = Vec3::ONE;
    match phase {
        PhaseFunction::Isotropic => ([one, z, z, z, z], 0.0),
        PhaseFunction::Rayleigh => ([z, one, z, z, z], 0.0),
        PhaseFunction::HenyeyGreenstein { g } => ([z, z, one, z, z], g),
        PhaseFunction::MieHazy => ([z, z, z, one, z], 0.0),
        PhaseFunction::MieMurky => ([z, z, z, z, one], 0.0),
        PhaseFunction::HoffmanPreetham { rayleigh, mie, g } => {
            let sum = rayleigh + mie; // validated > 0 per channel
            ([z, rayleigh / sum, mie / sum, z, z], g)
        }
    }
}

/// The eye–light distance below which the light is nudged away from the eye: at D = 0 the
/// airlight is infinite and the ray's angle to the light undefined.
const MIN_EYE_LIGHT_DISTANCE: f32 = 1e-6;

/// The length `L` of a directional light's ray parameter `s = x / (x + L)`: one extinction
/// length of the densest channel (steps uniform in `s` then follow the attenuation), 1 in a
/// clear medium.
pub(crate) fn directional_length(medium: &Medium) -> f32 {
    let sigma = medium.sigma_t().max_element();
    if sigma > 0.0 && (1.0 / sigma).is_finite() {
        1.0 / sigma
    } else {
        1.0
    }
}

impl AirlightUniform {
    pub fn new(
        eye: Vec3,
        light: &Light,
        medium: &Medium,
        pixel_angular_radius: f32,
        (table_along, table_across): (u32, u32),
    ) -> Self {
        let (light_pos, d) = match light.model().source() {
            // A directional light: its direction of travel, and the length of the ray
            // parameter s = x / (x + L) (see `shaders/shared/prelude.wgsl`).
            Source::Along(direction) => (direction, directional_length(medium)),
            Source::At(mut light_pos) => {
                let min_d = MIN_EYE_LIGHT_DISTANCE * eye.abs().max_element().max(1.0);
                if light_pos.distance(eye) < min_d {
                    light_pos = eye + Vec3::Y * min_d;
                }
                (light_pos, light_pos.distance(eye))
            }
        };
        let (lobes, g) = phase_lobes(medium.phase());
        let rgb = |v: Vec3| v.extend(0.0).to_array();
        Self {
            light_pos: light_pos.to_array(),
            distance: d,
            eye: eye.to_array(),
            pixel_radius: pixel_angular_radius,
            intensity: light.intensity().to_array(),
            hg_g: g,
            sigma_s: medium.sigma_s().to_array(),
            table_along,
            sigma_t: medium.sigma_t().to_array(),
            table_across,
            w_iso: rgb(lobes[0]),
            w_rayleigh: rgb(lobes[1]),
            w_hg: rgb(lobes[2]),
            w_hazy: rgb(lobes[3]),
            w_murky: rgb(lobes[4]),
        }
    }

    /// Only the phase function's lobes and a table size (`along` × `across`): what the
    /// indirect single scattering table depends on (every other field zero).
    pub fn phase_only(medium: &Medium, along: u32, across: u32) -> Self {
        let (lobes, g) = phase_lobes(medium.phase());
        let rgb = |v: Vec3| v.extend(0.0).to_array();
        Self {
            hg_g: g,
            table_along: along,
            table_across: across,
            w_iso: rgb(lobes[0]),
            w_rayleigh: rgb(lobes[1]),
            w_hg: rgb(lobes[2]),
            w_hazy: rgb(lobes[3]),
            w_murky: rgb(lobes[4]),
            ..Self::zeroed()
        }
    }

    /// The part of the uniform the F′ table depends on: D, σt, the phase and the table size.
    /// Eye and light may move freely as long as their distance stays the same.
    pub fn table_key(&self) -> Self {
        Self {
            light_pos: [0.0; 3],
            eye: [0.0; 3],
            pixel_radius: 0.0,
            intensity: [0.0; 3],
            sigma_s: [0.0; 3],
            ..*self
        }
    }
}

/// WGSL `View`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct ViewUniform {
    pub view_from_clip: [f32; 16],
    pub world_from_view: [f32; 16],
    pub size: [f32; 2],
    pub far_depth: f32,
}

impl ViewUniform {
    pub fn new(camera: &Camera, width: u32, height: u32) -> Self {
        Self {
            view_from_clip: camera.projection().inverse().to_cols_array(),
            world_from_view: camera.view().inverse().to_cols_array(),
            size: [width as f32, height as f32],
            far_depth: camera.far_depth(),
        }
    }
}

/// WGSL `Composite`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct CompositeUniform {
    pub sigma_t: [f32; 3],
    pub count: u32,
}

/// WGSL `Surfaces` (the composite's indirect single scattering term).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct SurfacesUniform {
    pub sigma_s: [f32; 3],
    pub count: u32,
    pub lights: [LightUniform; 4],
    /// The spot term's lattice spacing in pixels (0: evaluated at every pixel).
    pub lattice: u32,
}

impl SurfacesUniform {
    pub fn new(medium: &Medium, lights: &[Light]) -> Self {
        // The term is defined for lights at a position; a directional light adds none.
        let positioned: Vec<&Light> = lights.iter().filter(|l| l.position().is_some()).collect();
        let mut out = Self {
            sigma_s: medium.sigma_s().to_array(),
            count: positioned.len().min(4) as u32,
            ..Self::zeroed()
        };
        for (slot, light) in out.lights.iter_mut().zip(positioned) {
            *slot = LightUniform::new(light);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::{AirlightUniform, ViewUniform};
    use crate::light::{LightUniform, LIGHT_DIRECTIONAL, LIGHT_POINT, LIGHT_SPOT};
    use crate::nodes::layout::{assert_constants, assert_same, rust_layout};

    /// `crate::light`'s GPU form, which every node's shader holds, and the kinds' constants.
    #[test]
    fn the_light_s_layout_and_kinds_match_the_wgsl() {
        let rust = rust_layout!(LightUniform {
            position,
            kind,
            intensity,
            radius,
            axis,
            cos_half,
        });
        assert_same(rust, "#import prelude.wgsl", "Light");
        assert_constants(
            "#import prelude.wgsl",
            &[
                ("LIGHT_POINT", LIGHT_POINT),
                ("LIGHT_SPOT", LIGHT_SPOT),
                ("LIGHT_DIRECTIONAL", LIGHT_DIRECTIONAL),
            ],
        );
    }

    /// The prelude's structs, which every node's shader holds.
    #[test]
    fn prelude_layouts_match_the_wgsl() {
        let airlight = rust_layout!(AirlightUniform {
            light_pos,
            distance,
            eye,
            pixel_radius,
            intensity,
            hg_g,
            sigma_s,
            table_along,
            sigma_t,
            table_across,
            w_iso,
            w_rayleigh,
            w_hg,
            w_hazy,
            w_murky,
        });
        assert_same(airlight, "#import prelude.wgsl", "Airlight");
        let view = rust_layout!(ViewUniform {
            view_from_clip,
            world_from_view,
            size,
            far_depth,
        });
        assert_same(view, "#import prelude.wgsl", "View");
    }
}
