//! The shared, long-lived GPU objects: shader modules, bind group layouts and pipelines. One
//! `Cache` serves any number of nodes and views on the same device (as glyphon's `Cache`).

use std::collections::HashMap;
use std::sync::Mutex;

const PRELUDE: &str = include_str!("../../shaders/prelude.wgsl");

/// Shader modules, layouts and pipelines shared by every node on one device.
pub struct Cache {
    pub(crate) table_layout: wgpu::BindGroupLayout,
    pub(crate) table_pipeline: wgpu::ComputePipeline,
    pub(crate) march_layout: wgpu::BindGroupLayout,
    pub(crate) march_pipeline: wgpu::ComputePipeline,
    pub(crate) composite_layout: wgpu::BindGroupLayout,
    composite_pipeline_layout: wgpu::PipelineLayout,
    composite_module: wgpu::ShaderModule,
    composite_pipelines: Mutex<HashMap<wgpu::TextureFormat, wgpu::RenderPipeline>>,
}

/// Creates a shader module from the prelude followed by one node's WGSL.
fn module(device: &wgpu::Device, label: &str, node_source: &str) -> wgpu::ShaderModule {
    let source = format!("{PRELUDE}\n{node_source}");
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

fn uniform_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
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
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format: wgpu::TextureFormat::Rgba32Float,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
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
            ],
        });
        let march_module = module(
            device,
            "volshadow march.wgsl",
            include_str!("../../shaders/march.wgsl"),
        );
        let march_pipeline = compute_pipeline(
            device,
            "volshadow march",
            &march_layout,
            &march_module,
            "march",
        );

        let fragment = wgpu::ShaderStages::FRAGMENT;
        let composite_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("volshadow composite"),
            entries: &[
                uniform_entry(0, fragment),
                uniform_entry(1, fragment),
                texture_entry(2, fragment, UNFILTERED),
                texture_entry(3, fragment, wgpu::TextureSampleType::Depth),
                texture_entry(4, fragment, UNFILTERED),
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
        Self {
            table_layout,
            table_pipeline,
            march_layout,
            march_pipeline,
            composite_layout,
            composite_pipeline_layout,
            composite_module,
            composite_pipelines: Mutex::new(HashMap::new()),
        }
    }

    /// The composite pipeline writing `format`, built on first use.
    pub(crate) fn composite_pipeline(
        &self,
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
    ) -> wgpu::RenderPipeline {
        let mut pipelines = self
            .composite_pipelines
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        pipelines
            .entry(format)
            .or_insert_with(|| {
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
            .clone()
    }
}
