//! The light and its shadow map as the shared shadow-map visibility reads them
//! (`shaders/pcss.wgsl`): bind group 1 of the march's and the soft-shadow grid's pipelines.
//! The WGSL file declares the group; this module builds its layout, its parameters
//! ([`ShadowUniform`]) and its bind group ([`ShadowBinding`]) for both.

use bytemuck::{Pod, Zeroable};

use crate::gpu::pipeline::{bind_group, layout, Binding};
use crate::gpu::{depth_array_view, texture_2d, UniformBuffer};
use crate::nodes::light::LightUniform;
use crate::nodes::shadow_map::{standard_cube_near, ShadowMap};
use crate::nodes::soft_shadow::{soft_params, SoftLight, MAX_SOFT_SPHERES};
use crate::scene::Light;

/// Group 1's binding table (`shaders/pcss.wgsl`).
const BINDINGS: [Binding; 4] = [
    Binding::Params,     // shadow
    Binding::DepthArray, // shadow_map
    Binding::DepthArray, // shadow_back
    Binding::Comparison, // shadow_sampler
];

/// Group 1's layout, for a pipeline layout's second entry.
pub(crate) fn shadow_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    layout(
        device,
        "volshadow light and shadow map",
        wgpu::ShaderStages::COMPUTE,
        &BINDINGS,
    )
}

/// WGSL `LightShadow` (`shaders/pcss.wgsl`), field by field.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct ShadowUniform {
    pub light: LightUniform,
    pub faces: [[f32; 16]; 6],
    pub spheres: [[f32; 4]; MAX_SOFT_SPHERES],
    pub planes: [[f32; 4]; MAX_SOFT_SPHERES],
    pub depth_bias: f32,
    pub cube_near: f32,
    pub soft: SoftLight,
}

impl ShadowUniform {
    /// `light` with no shadow map: its description only.
    pub fn unshadowed(light: &Light) -> Self {
        Self {
            light: LightUniform::new(light),
            ..Self::zeroed()
        }
    }

    /// `light` with its shadow `map`, and with `soft` the soft estimate's constants (a light
    /// with a radius).
    pub fn new(light: &Light, map: &ShadowMap<'_>, soft: bool) -> Self {
        let mut out = Self::unshadowed(light);
        for (slot, face) in out.faces.iter_mut().zip(map.faces) {
            *slot = face.to_cols_array();
        }
        out.depth_bias = map.depth_bias;
        if let Light::Point(point) = light {
            out.cube_near = standard_cube_near(map.faces, point.position());
        }
        if soft {
            (out.soft, out.spheres, out.planes) = soft_params(light, map);
        }
        out
    }
}

/// One node's group 1: the parameters, the comparison sampler, and the bind group with the
/// shadow map it was made for (rebuilt only when the map changes).
pub(crate) struct ShadowBinding {
    layout: wgpu::BindGroupLayout,
    uniform: UniformBuffer<ShadowUniform>,
    sampler: wgpu::Sampler,
    /// Bound in place of a shadow map where there is none.
    dummy: wgpu::Texture,
    bound: Option<(wgpu::Texture, wgpu::Texture, wgpu::BindGroup)>,
}

impl ShadowBinding {
    /// `layout` is the pipelines' group-1 layout ([`shadow_layout`]).
    pub fn new(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, label: &str) -> Self {
        Self {
            layout: layout.clone(),
            uniform: UniformBuffer::new(device, label),
            sampler: device.create_sampler(&wgpu::SamplerDescriptor {
                label: Some("volshadow shadow compare"),
                mag_filter: wgpu::FilterMode::Linear,
                min_filter: wgpu::FilterMode::Linear,
                compare: Some(wgpu::CompareFunction::GreaterEqual),
                ..Default::default()
            }),
            dummy: texture_2d(
                device,
                "volshadow no shadow map",
                (1, 1, 1),
                wgpu::TextureFormat::Depth32Float,
                wgpu::TextureUsages::TEXTURE_BINDING,
            ),
            bound: None,
        }
    }

    /// Binds `map` (none: a 1×1 stand-in); returns whether the bind group was rebuilt.
    pub fn bind(&mut self, device: &wgpu::Device, map: Option<&ShadowMap<'_>>) -> bool {
        let front = map.map_or(&self.dummy, |m| m.texture);
        let back = map.and_then(|m| m.back).unwrap_or(front);
        if self
            .bound
            .as_ref()
            .is_some_and(|(f, b, _)| f == front && b == back)
        {
            return false;
        }
        let group = bind_group(
            device,
            "volshadow light and shadow map",
            &self.layout,
            [
                self.uniform.binding(),
                wgpu::BindingResource::TextureView(&depth_array_view(front)),
                wgpu::BindingResource::TextureView(&depth_array_view(back)),
                wgpu::BindingResource::Sampler(&self.sampler),
            ],
        );
        self.bound = Some((front.clone(), back.clone(), group));
        true
    }

    /// Writes `value` unless it is the last one written; returns whether it wrote.
    pub fn write(&mut self, queue: &wgpu::Queue, value: ShadowUniform) -> bool {
        self.uniform.write(queue, value)
    }

    /// The last parameters written.
    pub fn last(&self) -> Option<&ShadowUniform> {
        self.uniform.last()
    }

    /// The bind group of the last [`bind`](Self::bind).
    pub fn group(&self) -> Option<&wgpu::BindGroup> {
        self.bound.as_ref().map(|(_, _, g)| g)
    }
}

#[cfg(test)]
#[test]
fn the_shadow_parameters_match_the_wgsl() {
    use crate::nodes::layout::{assert_same, rust_layout};
    let source = "#import pcss.wgsl";
    let rust = rust_layout!(ShadowUniform {
        light,
        faces,
        spheres,
        planes,
        depth_bias,
        cube_near,
        soft,
    });
    assert_same(rust, source, "LightShadow");
    let soft = rust_layout!(SoftLight {
        nearest,
        spheres,
        cell_angle,
        reproject,
    });
    assert_same(soft, source, "SoftLight");
}
