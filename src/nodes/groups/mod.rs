//! What the nodes bind and no node owns, below every node (this folder imports none): the
//! shadow group (`shadow.rs`: group 1 of the march and the soft-shadow grid, the light and its
//! shadow map as `shaders/shared/pcss.wgsl` reads them, with a soft light's parameters), the shadow
//! map as its readers take it (`shadow_map.rs`: [`ShadowMap`](crate::nodes::ShadowMap) and
//! the parameters of [`SHADOW_WGSL`](crate::SHADOW_WGSL)), and the uniforms the per-pixel
//! passes share (`uniforms.rs`: the view, the airlight, the composite's). The light itself is
//! [`crate::light`]'s.

pub(crate) mod shadow;
pub(crate) mod shadow_map;
pub(crate) mod uniforms;
