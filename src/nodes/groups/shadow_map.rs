//! The shadow map node's output as the march and the soft-shadow grid read it ([`ShadowMap`]),
//! and the parameters [`SHADOW_WGSL`](crate::SHADOW_WGSL) takes to read it ([`ShadowParams`]).

use glam::{Mat4, Vec4};

use crate::error::{Error, Result};
use crate::light::Source;
use crate::scene::Light;

/// Bytes of one group of four triangles of [`ShadowMap::triangles`]: their corners and a
/// sphere bounding them, in 16 `vec4<f32>` (`shaders/passes/triangles.wgsl`).
pub(crate) const GROUP_BYTES: u64 = 256;

/// Most triangles (all occluders together) for which the node gathers
/// [`ShadowMap::triangles`]: each exact visible fraction tests every group of four's bounding
/// sphere, and the triangles of those in its cone of lines to the light, and the march takes
/// one at each piece of up to 64 refined steps of a marched interval (and two more in each of
/// at most 32 pieces split in thirds), with at most as many loop iterations as one turn over
/// 128 groups when it refines a sliver of the light. More, and the soft shadows take the
/// shadow map's estimate alone. On llvmpipe, which ends every loop of a shader invocation once
/// its loops together reach 65 535 iterations, 128 groups keep a ray's two intervals (a spot
/// light's cone may cut it in two), each at most 128 pieces and 32 of them in thirds, at
/// 2 × (128 + 64) × 128 = 49 152.
pub const MAX_EXACT_TRIANGLES: u32 = 512;

/// A shadow map as the march reads it.
#[derive(Clone, Copy)]
pub struct ShadowMap<'a> {
    /// Depth 2D array texture: 6 layers (cube faces +X, −X, +Y, −Y, +Z, −Z), 1 (spot), or one
    /// per cascade (directional, 1 to
    /// [`DirectionalLight::MAX_CASCADES`](crate::DirectionalLight::MAX_CASCADES), nearest
    /// first).
    pub texture: &'a wgpu::Texture,
    /// clip_from_world of each layer, reversed-Z infinite perspective, or for a directional
    /// light reversed-Z orthographic (see the module docs).
    pub faces: &'a [Mat4],
    /// Relative depth bias of a point or spot light's map (a directional map's is
    /// [`DIRECTIONAL_BIAS_TEXELS`](crate::nodes::DIRECTIONAL_BIAS_TEXELS) texels of each cascade,
    /// from its face).
    pub depth_bias: f32,
    /// The occluders' world-space bounding spheres (centre, radius), which bound where a light with
    /// a radius can cast a penumbra. [`ShadowMapNode`](crate::nodes::ShadowMapNode) takes each
    /// mesh's farthest vertex from its box's centre, so that a sphere's is its own radius, not its
    /// box's circumsphere (√3 times as large: on the report's soft scene its penumbra cone made the
    /// march at ½ resolution 1.44–1.49 times as long, alternated in one process). Empty (a shadow
    /// map rendered by the caller without them): a soft light's rays are marched whole.
    pub bounds: &'a [Vec4],
    /// For each of `bounds` (same order; missing or zero: none), a plane `(n, d)` with the
    /// occluder in `n·x ≤ d` and the light's sphere strictly beyond it: no line from a point
    /// beyond the plane to the light meets the occluder, so its penumbra lies in `n·x ≤ d`. A
    /// flat occluder such as a ground, whose bounding sphere holds the light, is bounded by it.
    pub planes: &'a [Vec4],
    /// A lower bound on the least distance from the light to an occluder: the distance to its
    /// bounding box, in its own frame or the world's, whichever is larger (tighter than
    /// `bounds`' spheres); 0 when not known.
    pub occluder_distance: f32,
    /// For a light with a radius: the nearest back faces (turned away from the light) of closed
    /// occluders, and the nearest faces of open ones, same size, format and layout as
    /// `texture`. Along a direction, a distance between the two surfaces estimates where the
    /// lines from a point to the light's disc graze the occluder (a sphere's silhouette), which
    /// the front surface alone puts too near the light. It is read only where `texture`
    /// holds a blocker (the node leaves a cube face no occluder reaches undrawn). `None`: the
    /// front surface is taken.
    pub back: Option<&'a wgpu::Texture>,
    /// Whether its occluders may leave gaps narrower than a light with a radius, through which
    /// it shines as a narrow shaft: more than one occluder, or one that is not convex
    /// ([`OccluderMesh::is_convex`](crate::gpu::OccluderMesh::is_convex)). Without, the
    /// [`SoftShadowNode`](crate::nodes::SoftShadowNode) skips its search for shafts. `true`
    /// where not known (a map the caller renders).
    pub gaps: bool,
    /// For a point or spot light with a radius whose occluders may leave gaps (see
    /// [`gaps`](Self::gaps)), at most [`MAX_EXACT_TRIANGLES`] triangles in all: the occluders'
    /// triangles in world space, in groups of four (each 16 `vec4<f32>`: the corners, then a
    /// sphere bounding them; zero triangles pad a group), from which the soft
    /// shadows take the light's visible fraction exactly in place of the shadow map's
    /// estimate, which sees the occluders from the light's centre alone (see
    /// [`SoftShadowNode`](crate::nodes::SoftShadowNode)). `None`: the estimate.
    pub triangles: Option<&'a wgpu::Buffer>,
    /// Changes whenever the map's contents do, so that what is derived from it (the
    /// [`SoftShadowNode`](crate::nodes::SoftShadowNode)'s grid) is rebuilt only then:
    /// [`ShadowMapNode`](crate::nodes::ShadowMapNode) counts its renders. A map the caller renders
    /// must change it at every render.
    pub generation: u64,
}

impl ShadowMap<'_> {
    /// The groups of four triangles in [`triangles`](Self::triangles), 0 without.
    pub(crate) fn triangle_groups(&self) -> u32 {
        self.triangles
            .map_or(0, |b| (b.size() / GROUP_BYTES) as u32)
    }

    /// Checks [`triangles`](Self::triangles): a storage buffer of whole groups of four, at most
    /// [`MAX_EXACT_TRIANGLES`] triangles.
    pub(crate) fn check_triangles(&self) -> Result<()> {
        let Some(buffer) = self.triangles else {
            return Ok(());
        };
        let problem = if !buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
            Some(format!("usage {:?} lacks STORAGE", buffer.usage()))
        } else if buffer.size() == 0 || buffer.size() % GROUP_BYTES != 0 {
            Some(format!(
                "{} bytes: not whole groups of {GROUP_BYTES} bytes",
                buffer.size()
            ))
        } else if buffer.size() / GROUP_BYTES * 4 > u64::from(MAX_EXACT_TRIANGLES) {
            Some(format!(
                "{} groups of four triangles: more than {MAX_EXACT_TRIANGLES} triangles",
                buffer.size() / GROUP_BYTES
            ))
        } else {
            None
        };
        match problem {
            Some(problem) => Err(Error::InvalidBuffer {
                field: "shadow_map.triangles",
                problem,
            }),
            None => Ok(()),
        }
    }

    /// Checks [`back`](Self::back) against the map: a depth array of the same size and layers.
    pub(crate) fn check_back(&self) -> Result<()> {
        let Some(back) = self.back else {
            return Ok(());
        };
        crate::gpu::check_depth_layers(
            "shadow_map.back",
            back,
            self.texture.depth_or_array_layers(),
        )?;
        if (back.width(), back.height()) != (self.texture.width(), self.texture.height()) {
            return Err(Error::InvalidTexture {
                field: "shadow_map.back",
                problem: format!(
                    "is {}x{}, the shadow map {}x{}",
                    back.width(),
                    back.height(),
                    self.texture.width(),
                    self.texture.height()
                ),
            });
        }
        Ok(())
    }

    /// The parameters [`SHADOW_WGSL`](crate::SHADOW_WGSL)'s `volshadow_shadow` takes (its
    /// `VolshadowShadow` struct), for the `light` this map was rendered for, with a normal
    /// offset of `normal_offset` × the distance from the light, or for a directional light
    /// `normal_offset` world units in its first cascade and as many texels in each other
    /// (`None`: two texels' angular size at this map's resolution, or two texels of a
    /// directional map's cascade, which keeps lit surfaces free of self-shadowing acne down to
    /// grazing angles of about 25°). The light's [radius](Light::radius) goes in
    /// [`ShadowParams::radius`], which makes a point or spot light's surface shadows soft.
    pub fn params(&self, light: &Light, normal_offset: Option<f32>) -> ShadowParams {
        let mut faces = [[0.0; 16]; 6];
        for (slot, m) in faces.iter_mut().zip(self.faces) {
            *slot = m.to_cols_array();
        }
        let texels = self.texture.width().max(1) as f32;
        let (light_position, directional, default_offset) = match light.model().source() {
            Source::Along(direction) => {
                // The first cascade's half width, from its first row (1 / half width).
                let half = self
                    .faces
                    .first()
                    .map(|m| 1.0 / m.row(0).truncate().length())
                    .filter(|h| h.is_finite() && *h > 0.0)
                    .unwrap_or(0.0);
                (direction, 1, 4.0 * half / texels)
            }
            Source::At(position) => (position, 0, 4.0 / texels),
        };
        let radius = light.model().radius();
        ShadowParams {
            faces,
            light_position: light_position.to_array(),
            depth_bias: self.depth_bias,
            layers: self.faces.len() as u32,
            normal_offset: normal_offset.unwrap_or(default_offset),
            directional,
            radius,
        }
    }
}

/// WGSL `VolshadowShadow` of [`SHADOW_WGSL`](crate::SHADOW_WGSL), byte for byte (upload it with
/// `bytemuck::bytes_of`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ShadowParams {
    /// clip_from_world of each layer, column-major (unused layers zero).
    pub faces: [[f32; 16]; 6],
    /// The light's position (a directional light: its direction of travel).
    pub light_position: [f32; 3],
    /// Relative depth bias.
    pub depth_bias: f32,
    /// 6 (point light, cube), 1 (spot light), or the cascades (directional light).
    pub layers: u32,
    /// Offset along the normal, relative to the distance from the light (a directional light:
    /// in world units in the first cascade, as many texels in the others).
    pub normal_offset: f32,
    /// 1 for a directional light's orthographic map, else 0.
    pub directional: u32,
    /// The light's radius ([`Light::radius`]): above 0, `volshadow_shadow` takes soft shadows
    /// (a blocker search and a filter, see [`SHADOW_WGSL`](crate::SHADOW_WGSL)); 0 (and a
    /// directional light, always 0 here) the hard lookup. Set it to 0 for hard surface shadows
    /// from a soft light's map.
    pub radius: f32,
}
#[cfg(test)]
mod tests {
    /// `SHADOW_WGSL` is pasted by callers on its own, so its spiral's hash (`volshadow_turn`)
    /// is a copy of the medium's (`soft_turn`, pcss.wgsl), the integer hash chosen for WGSL's
    /// precision (docs/METHOD.md §6): a change to one must reach the other.
    #[test]
    fn the_surface_and_the_medium_hash_alike() {
        let body = |source: &str, name: &str| -> String {
            let start = source
                .find(&format!("fn {name}("))
                .unwrap_or_else(|| panic!("{name} missing"));
            let rest = &source[start..];
            let from = rest.find("let b = bitcast").expect("the hash's first line");
            let to = rest.find("return").expect("the hash's return");
            rest[from..to].split_whitespace().collect()
        };
        let surface = body(crate::SHADOW_WGSL, "volshadow_turn");
        let medium = body(
            include_str!("../../../shaders/shared/pcss.wgsl"),
            "soft_turn",
        );
        assert!(surface.len() > 100, "the hash's text was not found");
        assert_eq!(
            surface, medium,
            "shadow.wgsl's hash differs from pcss.wgsl's"
        );
    }
}

#[cfg(test)]
#[test]
fn params_layout_matches_shadow_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let rust = rust_layout!(ShadowParams {
        faces,
        light_position,
        depth_bias,
        layers,
        normal_offset,
        directional,
        radius,
    });
    assert_same(rust, crate::SHADOW_WGSL, "VolshadowShadow");
}
