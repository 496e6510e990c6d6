//! A view's surfaces as volshadow's surface term reads them ([`volshadow::Surfaces`]): world
//! normals and diffuse albedo, one texel per pixel of the view's region, decoded from Bevy's
//! prepass textures. Bevy's normal prepass holds `n·½ + ½` (`Rgb10a2Unorm`, multisampled with
//! MSAA); its deferred G-buffer (`Rgba32Uint`) holds the base colour as `pow(rgb, 1/2.2)` in
//! four bytes of its first word and the metallic in the second byte of its third (bevy_pbr's
//! `deferred_gbuffer_from_pbr_input`).

use volshadow::wgpu;

use crate::resolve::MEDIAN_SAMPLE;
use crate::viewport::{full_target_pipeline, Region, RegionUniform, FULL_TARGET_VERTEX};

/// The decoded textures' format: normals in −1..1 and albedo, both read as floats.
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

const COMMON: &str = r"
// origin (xy) and size (zw) of the region read
@group(0) @binding(1) var<uniform> region: vec4<u32>;
// the albedo of every surface where there is no G-buffer (rgb)
@group(0) @binding(2) var<uniform> albedo: vec4<f32>;

struct Decoded {
    @location(0) normal: vec4<f32>,
    @location(1) albedo: vec4<f32>,
}

@fragment
fn fs(@builtin(position) p: vec4<f32>) -> Decoded {
    let pixel = vec2<i32>(p.xy) + vec2<i32>(region.xy);
    let s = sample_of(pixel);
    let encoded = load_normal(pixel, s);
    // Where the prepass drew nothing it holds its clear colour, black, which no unit normal
    // encodes: no surface term there.
    var n = vec3<f32>(0.0);
    if (any(encoded != vec3<f32>(0.0))) {
        n = encoded * 2.0 - 1.0;
    }
    return Decoded(vec4<f32>(n, 0.0), vec4<f32>(albedo_at(pixel), 1.0));
}
";

const SINGLE: &str = r"
@group(0) @binding(0) var normals: texture_2d<f32>;

fn sample_of(pixel: vec2<i32>) -> i32 {
    return 0;
}

fn load_normal(pixel: vec2<i32>, s: i32) -> vec3<f32> {
    return textureLoad(normals, pixel, 0).xyz;
}
";

// The sample the depth resolve picks (`MEDIAN_SAMPLE`), so that the normal is of the surface
// the resolved depth is of.
const MULTISAMPLED: &str = r"
@group(0) @binding(0) var normals: texture_multisampled_2d<f32>;
@group(0) @binding(3) var depth_ms: texture_depth_multisampled_2d;

fn sample_of(pixel: vec2<i32>) -> i32 {
    return median_sample(depth_ms, pixel);
}

fn load_normal(pixel: vec2<i32>, s: i32) -> vec3<f32> {
    return textureLoad(normals, pixel, s).xyz;
}
";

const FORWARD: &str = r"
fn albedo_at(pixel: vec2<i32>) -> vec3<f32> {
    return albedo.rgb;
}
";

// Bevy's deferred lighting's decode (`pbr_input_from_deferred_gbuffer`): base colour
// `pow(rgb, 2.2)`, and the diffuse colour `base · (1 − metallic)`. Unlit materials store a black
// base colour (their colour goes to the emissive word), so they reflect nothing.
const DEFERRED: &str = r"
@group(0) @binding(4) var gbuffer: texture_2d<u32>;

fn albedo_at(pixel: vec2<i32>) -> vec3<f32> {
    let g = textureLoad(gbuffer, pixel, 0);
    let base = pow(unpack4x8unorm(g.r).rgb, vec3<f32>(2.2));
    let metallic = unpack4x8unorm(g.b).g;
    return base * (1.0 - metallic);
}
";

/// What a view's surfaces are decoded from: the normal prepass, the multisampled depth it is
/// resolved with (with MSAA), and the deferred G-buffer (for a deferred camera).
pub(crate) struct SurfaceSources<'a> {
    pub(crate) normal: &'a wgpu::Texture,
    pub(crate) depth: &'a wgpu::Texture,
    pub(crate) gbuffer: Option<&'a wgpu::Texture>,
}

/// The decode's pipelines: one per (multisampled, deferred).
pub(crate) struct SurfaceDecode {
    pipelines: [Decode; 4],
}

struct Decode {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

impl Decode {
    fn new(device: &wgpu::Device, multisampled: bool, deferred: bool) -> Self {
        let label = "volshadow_bevy surfaces";
        let sampling = if multisampled {
            format!("{MEDIAN_SAMPLE}{MULTISAMPLED}")
        } else {
            SINGLE.to_string()
        };
        let source = format!(
            "{FULL_TARGET_VERTEX}{COMMON}{sampling}{}",
            if deferred { DEFERRED } else { FORWARD }
        );
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let texture = |binding, sample_type, multisampled| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled,
            },
            count: None,
        };
        let float = wgpu::TextureSampleType::Float { filterable: false };
        let mut entries = vec![
            texture(0, float, multisampled),
            RegionUniform::layout_entry(1),
            // The albedo: a 16-byte fragment uniform, as the region's.
            RegionUniform::layout_entry(2),
        ];
        if multisampled {
            entries.push(texture(3, wgpu::TextureSampleType::Depth, true));
        }
        if deferred {
            entries.push(texture(4, wgpu::TextureSampleType::Uint, false));
        }
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(label),
            entries: &entries,
        });
        let pipeline = full_target_pipeline(
            device,
            label,
            &module,
            &layout,
            &[Some(FORMAT.into()), Some(FORMAT.into())],
            None,
        );
        Self { pipeline, layout }
    }
}

impl SurfaceDecode {
    pub(crate) fn new(device: &wgpu::Device) -> Self {
        Self {
            pipelines: [(false, false), (false, true), (true, false), (true, true)]
                .map(|(ms, deferred)| Decode::new(device, ms, deferred)),
        }
    }

    fn of(&self, multisampled: bool, deferred: bool) -> &Decode {
        &self.pipelines[usize::from(multisampled) * 2 + usize::from(deferred)]
    }

    /// The normal and albedo textures of `region` of `sources` (`kept` when made for them),
    /// to be written by [`encode`](Self::encode) as the view records.
    pub(crate) fn prepare<'a>(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        kept: &'a mut Option<DecodedSurfaces>,
        sources: &SurfaceSources<'_>,
        region: Region,
        albedo: volshadow::glam::Vec3,
    ) -> &'a DecodedSurfaces {
        let multisampled = sources.normal.sample_count() > 1;
        let fits = |d: &DecodedSurfaces| {
            d.normal.size() == region.extent()
                && d.normal_source == *sources.normal
                && (!multisampled || d.depth_source == *sources.depth)
                && d.gbuffer_source.as_ref() == sources.gbuffer
        };
        if !kept.as_ref().is_some_and(fits) {
            let usage =
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
            let texture = |label| region.texture(device, label, FORMAT, usage);
            let (normal, albedo_texture) = (
                texture("volshadow_bevy surface normals"),
                texture("volshadow_bevy surface albedo"),
            );
            let decode = self.of(multisampled, sources.gbuffer.is_some());
            let uniform = RegionUniform::new(device, "volshadow_bevy surfaces region");
            let albedo_buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("volshadow_bevy surfaces albedo"),
                size: 16,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let views: Vec<(u32, wgpu::TextureView)> = [
                Some((0, sources.normal)),
                multisampled.then_some((3, sources.depth)),
                sources.gbuffer.map(|g| (4, g)),
            ]
            .into_iter()
            .flatten()
            .map(|(binding, texture)| {
                let aspect = if texture.format().is_depth_stencil_format() {
                    wgpu::TextureAspect::DepthOnly
                } else {
                    wgpu::TextureAspect::All
                };
                let view = texture.create_view(&wgpu::TextureViewDescriptor {
                    aspect,
                    ..Default::default()
                });
                (binding, view)
            })
            .collect();
            let mut entries: Vec<wgpu::BindGroupEntry> = views
                .iter()
                .map(|(binding, view)| wgpu::BindGroupEntry {
                    binding: *binding,
                    resource: wgpu::BindingResource::TextureView(view),
                })
                .collect();
            entries.push(wgpu::BindGroupEntry {
                binding: 1,
                resource: uniform.buffer.as_entire_binding(),
            });
            entries.push(wgpu::BindGroupEntry {
                binding: 2,
                resource: albedo_buffer.as_entire_binding(),
            });
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("volshadow_bevy surfaces"),
                layout: &decode.layout,
                entries: &entries,
            });
            *kept = Some(DecodedSurfaces {
                normal_source: sources.normal.clone(),
                depth_source: sources.depth.clone(),
                gbuffer_source: sources.gbuffer.cloned(),
                targets: [
                    normal.create_view(&Default::default()),
                    albedo_texture.create_view(&Default::default()),
                ],
                normal,
                albedo: albedo_texture,
                region: uniform,
                albedo_buffer,
                albedo_value: None,
                bind_group,
            });
        }
        let decoded = kept.as_mut().expect("made above");
        decoded.region.set(queue, region);
        if decoded.albedo_value != Some(albedo) {
            let bytes: Vec<u8> = albedo
                .extend(1.0)
                .to_array()
                .iter()
                .flat_map(|v| v.to_le_bytes())
                .collect();
            queue.write_buffer(&decoded.albedo_buffer, 0, &bytes);
            decoded.albedo_value = Some(albedo);
        }
        decoded
    }

    /// Records the decode that [`prepare`](Self::prepare) set up.
    pub(crate) fn encode(&self, encoder: &mut wgpu::CommandEncoder, decoded: &DecodedSurfaces) {
        let attachment = |view| {
            Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("volshadow_bevy surfaces"),
            color_attachments: &[
                attachment(&decoded.targets[0]),
                attachment(&decoded.targets[1]),
            ],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let decode = self.of(
            decoded.normal_source.sample_count() > 1,
            decoded.gbuffer_source.is_some(),
        );
        pass.set_pipeline(&decode.pipeline);
        pass.set_bind_group(0, &decoded.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// A view's decoded surfaces: the textures volshadow reads, and the bind group reading the
/// sources they were made for (Bevy keeps a view's prepass textures while its size stays).
pub(crate) struct DecodedSurfaces {
    normal_source: wgpu::Texture,
    depth_source: wgpu::Texture,
    gbuffer_source: Option<wgpu::Texture>,
    pub(crate) normal: wgpu::Texture,
    pub(crate) albedo: wgpu::Texture,
    targets: [wgpu::TextureView; 2],
    region: RegionUniform,
    albedo_buffer: wgpu::Buffer,
    albedo_value: Option<volshadow::glam::Vec3>,
    bind_group: wgpu::BindGroup,
}
