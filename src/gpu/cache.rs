//! The shared, long-lived GPU objects: shader modules, bind group layouts and pipelines. One
//! `Cache` serves any number of nodes and views on the same device (as glyphon's `Cache`).

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

const PRELUDE: &str = include_str!("../../shaders/prelude.wgsl");

/// Shader modules, layouts and pipelines shared by every node on one device. Cloning is
/// cheap (handles).
///
/// Used in the [crate-level example](crate#example).
#[derive(Clone)]
pub struct Cache {
    pub(crate) table_layout: wgpu::BindGroupLayout,
    pub(crate) table_pipeline: wgpu::ComputePipeline,
    pub(crate) march_layout: wgpu::BindGroupLayout,
    march_pipeline_layout: wgpu::PipelineLayout,
    march_module: wgpu::ShaderModule,
    march_pipelines: Arc<Mutex<HashMap<MarchVariant, wgpu::ComputePipeline>>>,
    pub(crate) composite_layout: wgpu::BindGroupLayout,
    pub(crate) light_texture_layout: wgpu::BindGroupLayout,
    pub(crate) light_copy_pipeline: wgpu::RenderPipeline,
    pub(crate) light_down_pipeline: wgpu::RenderPipeline,
    pub(crate) upsample_layout: wgpu::BindGroupLayout,
    upsample_pipeline_layout: wgpu::PipelineLayout,
    upsample_module: wgpu::ShaderModule,
    upsample_pipelines: Arc<Mutex<HashMap<bool, UpsamplePipelines>>>,
    pub(crate) shadow_layout: wgpu::BindGroupLayout,
    pub(crate) shadow_pipeline: wgpu::RenderPipeline,
    pub(crate) extents_extrude_layout: wgpu::BindGroupLayout,
    pub(crate) extents_reset_pipeline: wgpu::ComputePipeline,
    pub(crate) extents_extrude_pipeline: wgpu::ComputePipeline,
    pub(crate) extents_raster_layout: wgpu::BindGroupLayout,
    pub(crate) extents_front_pipeline: wgpu::RenderPipeline,
    pub(crate) extents_back_near_pipeline: wgpu::RenderPipeline,
    pub(crate) extents_back_far_pipeline: wgpu::RenderPipeline,
    pub(crate) extents_crossings_layout: wgpu::BindGroupLayout,
    pub(crate) extents_crossings_pipeline: wgpu::RenderPipeline,
    composite_pipeline_layout: wgpu::PipelineLayout,
    composite_module: wgpu::ShaderModule,
    composite_pipelines: Arc<Mutex<HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>>>,
}

/// The march shader's pipeline constants (see `shaders/march.wgsl`): one pipeline each.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct MarchVariant {
    /// 0 analytic, 1 hybrid, 2 brute force.
    pub mode: u32,
    pub spot: bool,
    pub textured: bool,
    pub bisections: u32,
}

/// The upsample's entry points for one kind of light.
#[derive(Clone)]
pub(crate) struct UpsamplePipelines {
    /// Bilinear and 3×3 (one pass).
    pub single: wgpu::ComputePipeline,
    /// The separable filter's horizontal and vertical passes.
    pub horizontal: wgpu::ComputePipeline,
    pub vertical: wgpu::ComputePipeline,
}

/// The value for `key` in a cache shared between clones, made on first use.
fn cached<K: std::hash::Hash + Eq, V: Clone>(
    map: &Mutex<HashMap<K, V>>,
    key: K,
    make: impl FnOnce() -> V,
) -> V {
    map.lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
        .entry(key)
        .or_insert_with(make)
        .clone()
}

/// Creates a shader module from the prelude followed by one node's WGSL.
fn module(device: &wgpu::Device, label: &str, node_source: &str) -> wgpu::ShaderModule {
    let source = format!("{PRELUDE}\n{node_source}");
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

/// A node's per-frame parameters. They are read-only *storage* buffers, not uniform buffers:
/// Mesa's lavapipe (22.x) specialises a shader on the contents of its uniform buffers
/// ("inlinable uniforms") at every submission, compiling a new variant with LLVM for every new
/// value and never freeing it (≈ 0.5–1 MB and up to hundreds of ms per frame and shader).
/// Storage buffers are never inlined.
fn uniform_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn texture_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

fn storage_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    storage_texture_entry(binding, wgpu::TextureFormat::Rgba32Float)
}

fn storage_texture_entry(binding: u32, format: wgpu::TextureFormat) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

fn buffer_entry(
    binding: u32,
    ty: wgpu::BufferBindingType,
    dynamic: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A depth-only render pipeline (no colour target). `compare: None` tests and writes nothing
/// (a pass whose fragments only write storage buffers).
#[allow(clippy::too_many_arguments)]
fn depth_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    vertex_entry: &str,
    fragment_entry: Option<&str>,
    buffers: &[wgpu::VertexBufferLayout<'_>],
    compare: Option<wgpu::CompareFunction>,
) -> wgpu::RenderPipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex_entry),
            compilation_options: Default::default(),
            buffers: &buffers.iter().cloned().map(Some).collect::<Vec<_>>(),
        },
        // Both sides: occluders may be open meshes; volume faces are classified in the shader.
        primitive: wgpu::PrimitiveState {
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(compare.is_some()),
            depth_compare: Some(compare.unwrap_or(wgpu::CompareFunction::Always)),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: fragment_entry.map(|entry| wgpu::FragmentState {
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            targets: &[],
        }),
        multiview_mask: None,
        cache: None,
    })
}

const UNFILTERED: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };

fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    entry_point: &str,
) -> wgpu::ComputePipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module,
        entry_point: Some(entry_point),
        compilation_options: Default::default(),
        cache: None,
    })
}

impl Cache {
    /// Compiles the shaders and builds the layouts and compute pipelines. Render pipelines for
    /// the composite are built per output format on first use.
    ///
    /// Used in the [crate-level example](crate#example).
    pub fn new(device: &wgpu::Device) -> Self {
        let compute = wgpu::ShaderStages::COMPUTE;
        let table_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow airlight table"),
            entries: &[uniform_entry(0, compute), storage_entry(1)],
        });
        let table_module = module(
            device,
            "volshadow airlight_table.wgsl",
            include_str!("../../shaders/airlight_table.wgsl"),
        );
        let table_pipeline = compute_pipeline(
            device,
            "volshadow airlight table",
            &table_layout,
            &table_module,
            "build",
        );

        let march_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow march"),
            entries: &[
                uniform_entry(0, compute),
                uniform_entry(1, compute),
                texture_entry(2, compute, UNFILTERED),
                texture_entry(3, compute, wgpu::TextureSampleType::Depth),
                storage_entry(4),
                uniform_entry(5, compute),
                wgpu::BindGroupLayoutEntry {
                    binding: 6,
                    visibility: compute,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 7,
                    visibility: compute,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
                texture_entry(8, compute, wgpu::TextureSampleType::Depth),
                texture_entry(9, compute, wgpu::TextureSampleType::Depth),
                texture_entry(10, compute, wgpu::TextureSampleType::Depth),
                storage_texture_entry(11, wgpu::TextureFormat::R32Uint),
                texture_entry(
                    12,
                    compute,
                    wgpu::TextureSampleType::Float { filterable: true },
                ),
                wgpu::BindGroupLayoutEntry {
                    binding: 13,
                    visibility: compute,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
                buffer_entry(
                    14,
                    wgpu::BufferBindingType::Storage { read_only: true },
                    false,
                ),
                buffer_entry(
                    15,
                    wgpu::BufferBindingType::Storage { read_only: true },
                    false,
                ),
                buffer_entry(
                    16,
                    wgpu::BufferBindingType::Storage { read_only: false },
                    false,
                ),
            ],
        });
        let march_module = module(
            device,
            "volshadow march.wgsl",
            include_str!("../../shaders/march.wgsl"),
        );
        let march_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("volshadow march"),
                bind_group_layouts: &[Some(&march_layout)],
                immediate_size: 0,
            });

        let fragment = wgpu::ShaderStages::FRAGMENT;
        let composite_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow composite"),
            entries: &[
                uniform_entry(0, fragment),
                uniform_entry(1, fragment),
                texture_entry(2, fragment, UNFILTERED),
                texture_entry(3, fragment, wgpu::TextureSampleType::Depth),
                texture_entry(4, fragment, UNFILTERED),
                texture_entry(5, fragment, UNFILTERED),
                texture_entry(6, fragment, UNFILTERED),
                texture_entry(7, fragment, UNFILTERED),
            ],
        });
        let composite_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("volshadow composite"),
                bind_group_layouts: &[Some(&composite_layout)],
                immediate_size: 0,
            });
        let composite_module = module(
            device,
            "volshadow composite.wgsl",
            include_str!("../../shaders/composite.wgsl"),
        );
        let vertex = wgpu::ShaderStages::VERTEX;
        // Storage, not uniform: see `uniform_entry`.
        let dynamic_uniform = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: vertex,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: true,
                min_binding_size: wgpu::BufferSize::new(64),
            },
            count: None,
        };
        let shadow_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow shadow map"),
            entries: &[dynamic_uniform(0), dynamic_uniform(1)],
        });
        let shadow_module = module(
            device,
            "volshadow shadow_map.wgsl",
            include_str!("../../shaders/shadow_map.wgsl"),
        );
        let shadow_pipeline = depth_pipeline(
            device,
            "volshadow shadow map",
            &shadow_layout,
            &shadow_module,
            "vs_shadow",
            None,
            &[wgpu::VertexBufferLayout {
                array_stride: 16,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x4],
            }],
            Some(wgpu::CompareFunction::Greater),
        );

        let storage = |read_only| wgpu::BufferBindingType::Storage { read_only };
        let extents_extrude_layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("volshadow extrude"),
                entries: &[
                    buffer_entry(0, storage(true), false),
                    buffer_entry(1, storage(true), false),
                    buffer_entry(2, storage(true), false),
                    buffer_entry(3, storage(true), false),
                    buffer_entry(4, storage(false), false),
                    buffer_entry(5, storage(false), false),
                ],
            });
        let extents_module = module(
            device,
            "volshadow extents.wgsl",
            include_str!("../../shaders/extents.wgsl"),
        );
        let extents_reset_pipeline = compute_pipeline(
            device,
            "volshadow extrude reset",
            &extents_extrude_layout,
            &extents_module,
            "reset",
        );
        let extents_extrude_pipeline = compute_pipeline(
            device,
            "volshadow extrude",
            &extents_extrude_layout,
            &extents_module,
            "extrude",
        );
        let extents_raster_layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("volshadow extents raster"),
                entries: &[uniform_entry(0, vertex)],
            });
        let volume_vertices = [wgpu::VertexBufferLayout {
            array_stride: 32,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4],
        }];
        let extents_pipeline = |label, entry, compare| {
            depth_pipeline(
                device,
                label,
                &extents_raster_layout,
                &extents_module,
                "vs_volume",
                Some(entry),
                &volume_vertices,
                Some(compare),
            )
        };
        // Reversed Z: nearest = greatest depth.
        let extents_front_pipeline = extents_pipeline(
            "volshadow extents front",
            "fs_front",
            wgpu::CompareFunction::Greater,
        );
        let extents_back_near_pipeline = extents_pipeline(
            "volshadow extents back near",
            "fs_back",
            wgpu::CompareFunction::Greater,
        );
        let extents_back_far_pipeline = extents_pipeline(
            "volshadow extents back far",
            "fs_back",
            wgpu::CompareFunction::Less,
        );
        // Exact mode: every crossing appended to per-pixel lists from the fragment stage
        // (storage buffers and atomics there are core WebGPU).
        let fragment_storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: fragment,
            ty: wgpu::BindingType::Buffer {
                ty: storage(false),
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let extents_crossings_layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("volshadow extents crossings"),
                entries: &[
                    uniform_entry(0, vertex),
                    uniform_entry(1, fragment),
                    uniform_entry(2, fragment),
                    texture_entry(3, fragment, wgpu::TextureSampleType::Depth),
                    fragment_storage(4),
                    fragment_storage(5),
                ],
            });
        let extents_crossings_pipeline = depth_pipeline(
            device,
            "volshadow extents crossings",
            &extents_crossings_layout,
            &extents_module,
            "vs_volume",
            Some("fs_crossings"),
            &volume_vertices,
            None,
        );

        let upsample_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow upsample"),
            entries: &[
                uniform_entry(0, compute),
                uniform_entry(1, compute),
                texture_entry(2, compute, UNFILTERED),
                texture_entry(3, compute, wgpu::TextureSampleType::Depth),
                texture_entry(4, compute, UNFILTERED),
                storage_entry(5),
                texture_entry(6, compute, UNFILTERED),
                uniform_entry(7, compute),
                uniform_entry(8, compute),
            ],
        });
        let upsample_module = module(
            device,
            "volshadow upsample.wgsl",
            include_str!("../../shaders/upsample.wgsl"),
        );
        let upsample_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("volshadow upsample"),
                bind_group_layouts: &[Some(&upsample_layout)],
                immediate_size: 0,
            });

        let light_texture_layout =
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("volshadow light texture"),
                entries: &[
                    texture_entry(
                        0,
                        fragment,
                        wgpu::TextureSampleType::Float { filterable: true },
                    ),
                    wgpu::BindGroupLayoutEntry {
                        binding: 1,
                        visibility: fragment,
                        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                        count: None,
                    },
                ],
            });
        let light_module = module(
            device,
            "volshadow light_texture.wgsl",
            include_str!("../../shaders/light_texture.wgsl"),
        );
        let light_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("volshadow light texture"),
                bind_group_layouts: &[Some(&light_texture_layout)],
                immediate_size: 0,
            });
        let light_pipeline = |entry| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("volshadow light texture"),
                layout: Some(&light_pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &light_module,
                    entry_point: Some("vs_fullscreen"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: Default::default(),
                depth_stencil: None,
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &light_module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::TextureFormat::Rgba16Float.into())],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let (light_copy_pipeline, light_down_pipeline) =
            (light_pipeline("fs_copy"), light_pipeline("fs_down"));

        Self {
            light_texture_layout,
            light_copy_pipeline,
            light_down_pipeline,
            upsample_layout,
            upsample_pipeline_layout,
            upsample_module,
            upsample_pipelines: Arc::new(Mutex::new(HashMap::new())),
            shadow_layout,
            shadow_pipeline,
            extents_extrude_layout,
            extents_reset_pipeline,
            extents_extrude_pipeline,
            extents_raster_layout,
            extents_front_pipeline,
            extents_back_near_pipeline,
            extents_back_far_pipeline,
            extents_crossings_layout,
            extents_crossings_pipeline,
            table_layout,
            table_pipeline,
            march_layout,
            march_pipeline_layout,
            march_module,
            march_pipelines: Arc::new(Mutex::new(HashMap::new())),
            composite_layout,
            composite_pipeline_layout,
            composite_module,
            composite_pipelines: Arc::new(Mutex::new(HashMap::new())),
        }
    }

    /// The composite pipeline writing `format`, built on first use.
    pub(crate) fn composite_pipeline(
        &self,
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
    ) -> wgpu::RenderPipeline {
        cached(&self.composite_pipelines, format, || {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("volshadow composite"),
                layout: Some(&self.composite_pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &self.composite_module,
                    entry_point: Some("vs_fullscreen"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState::default(),
                depth_stencil: None,
                multisample: wgpu::MultisampleState::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &self.composite_module,
                    entry_point: Some("fs_composite"),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        })
    }

    /// The march pipeline for `variant`, built on first use.
    pub(crate) fn march_pipeline(
        &self,
        device: &wgpu::Device,
        variant: MarchVariant,
    ) -> wgpu::ComputePipeline {
        cached(&self.march_pipelines, variant, || {
            let flag = |b: bool| if b { 1.0 } else { 0.0 };
            let constants = [
                ("MODE", f64::from(variant.mode)),
                ("SPOT", flag(variant.spot)),
                ("TEXTURED", flag(variant.textured)),
                ("BISECTIONS", f64::from(variant.bisections)),
            ];
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("volshadow march"),
                layout: Some(&self.march_pipeline_layout),
                module: &self.march_module,
                entry_point: Some("march"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            })
        })
    }

    /// The upsample pipelines for a spot (`true`) or point light, built on first use.
    pub(crate) fn upsample_pipelines(
        &self,
        device: &wgpu::Device,
        spot: bool,
    ) -> UpsamplePipelines {
        cached(&self.upsample_pipelines, spot, || {
            let constants = [("SPOT", if spot { 1.0 } else { 0.0 })];
            let pipeline = |entry| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some("volshadow upsample"),
                    layout: Some(&self.upsample_pipeline_layout),
                    module: &self.upsample_module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: &constants,
                        ..Default::default()
                    },
                    cache: None,
                })
            };
            UpsamplePipelines {
                single: pipeline("upsample"),
                horizontal: pipeline("separable_h"),
                vertical: pipeline("separable_v"),
            }
        })
    }
}
