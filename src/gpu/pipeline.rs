//! The helpers the nodes build their GPU objects with: binding tables, bind groups and
//! layouts, shader modules (a node's WGSL with its imports, [`wgsl::compose`]),
//! compute, depth and fullscreen pipelines, and timed compute dispatches.

use std::collections::HashMap;
use std::sync::Mutex;

use crate::gpu::precision::ShaderPrecision;
use crate::gpu::wgsl::{self, Wgsl};
use crate::gpu::GpuTimer;
use crate::pass::Pass;

/// What one binding of a node's bind group holds. Each node lists its bindings once, in a
/// `const` table whose entry `i` is `@binding(i)` of its WGSL; the layout ([`layout`]) and
/// every bind group ([`bind_group`], which takes one resource per entry) are built from it.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Binding {
    /// Per-frame parameters: a read-only *storage* buffer, not a uniform buffer. Mesa's
    /// lavapipe (22.x) specialises a shader on the contents of its uniform buffers ("inlinable
    /// uniforms") at every submission, compiling a new variant with LLVM for every new value and
    /// never freeing it (≈ 0.5–1 MB and up to hundreds of ms per frame and shader). Storage
    /// buffers are never inlined.
    Params,
    /// [`Binding::Params`] read by the vertex stage only, whatever the layout's stages.
    VertexParams,
    /// [`Binding::Params`] with a dynamic offset, in slots of this many bytes.
    DynamicParams(u64),
    /// A read-write storage buffer (never visible to the vertex stage).
    ReadWrite,
    /// A 2D float texture read with `textureLoad`.
    Texture,
    /// A 2D unsigned-integer texture read with `textureLoad`.
    UintTexture,
    /// A 2D float texture read through a filtering sampler.
    Filterable,
    /// A 2D depth texture.
    Depth,
    /// A 2D array depth texture (a shadow map).
    DepthArray,
    /// A write-only 2D storage texture.
    Storage(wgpu::TextureFormat),
    /// A 3D float texture read through a filtering sampler.
    Volume,
    /// A 3D float texture read with `textureLoad` (any float format, 32-bit ones included).
    VolumeLoad,
    /// A write-only 3D storage texture.
    StorageVolume(wgpu::TextureFormat),
    /// A filtering sampler.
    Sampler,
    /// A comparison sampler.
    Comparison,
}

impl Binding {
    fn entry(self, binding: u32, stages: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
        let texture = |sample_type, view_dimension| wgpu::BindingType::Texture {
            sample_type,
            view_dimension,
            multisampled: false,
        };
        let buffer = |read_only, has_dynamic_offset, size| wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset,
            min_binding_size: wgpu::BufferSize::new(size),
        };
        let d2 = wgpu::TextureViewDimension::D2;
        let (ty, visibility) = match self {
            Binding::Params => (buffer(true, false, 0), stages),
            Binding::VertexParams => (buffer(true, false, 0), wgpu::ShaderStages::VERTEX),
            Binding::DynamicParams(size) => (buffer(true, true, size), stages),
            Binding::ReadWrite => (buffer(false, false, 0), stages - wgpu::ShaderStages::VERTEX),
            Binding::Texture => (
                texture(wgpu::TextureSampleType::Float { filterable: false }, d2),
                stages,
            ),
            Binding::UintTexture => (texture(wgpu::TextureSampleType::Uint, d2), stages),
            Binding::Filterable => (
                texture(wgpu::TextureSampleType::Float { filterable: true }, d2),
                stages,
            ),
            Binding::Depth => (texture(wgpu::TextureSampleType::Depth, d2), stages),
            Binding::DepthArray => (
                texture(
                    wgpu::TextureSampleType::Depth,
                    wgpu::TextureViewDimension::D2Array,
                ),
                stages,
            ),
            Binding::Storage(format) => (
                wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format,
                    view_dimension: d2,
                },
                stages,
            ),
            Binding::Volume => (
                texture(
                    wgpu::TextureSampleType::Float { filterable: true },
                    wgpu::TextureViewDimension::D3,
                ),
                stages,
            ),
            Binding::VolumeLoad => (
                texture(
                    wgpu::TextureSampleType::Float { filterable: false },
                    wgpu::TextureViewDimension::D3,
                ),
                stages,
            ),
            Binding::StorageVolume(format) => (
                wgpu::BindingType::StorageTexture {
                    access: wgpu::StorageTextureAccess::WriteOnly,
                    format,
                    view_dimension: wgpu::TextureViewDimension::D3,
                },
                stages,
            ),
            Binding::Sampler => (
                wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                stages,
            ),
            Binding::Comparison => (
                wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                stages,
            ),
        };
        wgpu::BindGroupLayoutEntry {
            binding,
            visibility,
            ty,
            count: None,
        }
    }
}

/// The bind group layout of a binding table (entry `i` is binding `i`).
pub(crate) fn layout(
    device: &wgpu::Device,
    label: &str,
    stages: wgpu::ShaderStages,
    bindings: &[Binding],
) -> wgpu::BindGroupLayout {
    let entries: Vec<_> = (0u32..)
        .zip(bindings)
        .map(|(i, b)| b.entry(i, stages))
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &entries,
    })
}

/// A bind group with one resource per entry of the layout's binding table, in its order.
pub(crate) fn bind_group<const N: usize>(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: [wgpu::BindingResource<'_>; N],
) -> wgpu::BindGroup {
    let entries: Vec<_> = (0u32..)
        .zip(resources)
        .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// The value for `key` in a cache shared between clones, made on first use.
pub(crate) fn cached<K: std::hash::Hash + Eq, V: Clone>(
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

/// Creates the shader module of `source` with its imports ([`wgsl::compose`]), labelled
/// `volshadow <name>`.
pub(crate) fn module(
    device: &wgpu::Device,
    source: &Wgsl<'_>,
    precision: ShaderPrecision,
) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(&format!("volshadow {}", source.name)),
        source: wgpu::ShaderSource::Wgsl(wgsl::compose(source, precision).text.into()),
    })
}

/// A pipeline layout of bind groups `0..layouts.len()`.
fn pipeline_layout(
    device: &wgpu::Device,
    label: &str,
    layouts: &[&wgpu::BindGroupLayout],
) -> wgpu::PipelineLayout {
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().copied().map(Some).collect();
    device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &layouts,
        immediate_size: 0,
    })
}

/// A compute pipeline of bind groups `0..layouts.len()` with pipeline-overridable `constants`.
pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    layouts: &[&wgpu::BindGroupLayout],
    module: &wgpu::ShaderModule,
    entry_point: &str,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout(device, label, layouts)),
        module,
        entry_point: Some(entry_point),
        compilation_options: wgpu::PipelineCompilationOptions {
            constants,
            ..Default::default()
        },
        cache: None,
    })
}

/// One dispatch of a compute pass: the pipeline, its bind groups `0..`, the workgroups.
pub(crate) type Dispatch<'a> = (
    &'a wgpu::ComputePipeline,
    &'a [&'a wgpu::BindGroup],
    (u32, u32, u32),
);

/// Records one compute pass, timed as `pass` when a timer is given, of one dispatch per entry
/// of `dispatches` (pipeline, bind groups `0..`, workgroups) in order: what a node's `encode`
/// does.
pub(crate) fn dispatch(
    encoder: &mut wgpu::CommandEncoder,
    timer: Option<&mut GpuTimer>,
    pass: Pass,
    label: &str,
    dispatches: &[Dispatch<'_>],
) {
    let timestamp_writes = timer.and_then(|t| t.compute_pass(pass));
    let mut compute = crate::gpu::passes::begin_compute(
        encoder,
        &wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes,
        },
    );
    for &(pipeline, bind_groups, groups) in dispatches {
        compute.set_pipeline(pipeline);
        for (index, bind_group) in (0u32..).zip(bind_groups) {
            compute.set_bind_group(index, *bind_group, &[]);
        }
        compute.dispatch_workgroups(groups.0, groups.1, groups.2);
    }
}

/// A depth-only render pipeline (no colour target). `compare: None` tests and writes nothing
/// (a pass whose fragments only write storage buffers).
#[allow(clippy::too_many_arguments)]
pub(crate) fn depth_pipeline(
    device: &wgpu::Device,
    label: &str,
    layouts: &[&wgpu::BindGroupLayout],
    module: &wgpu::ShaderModule,
    vertex_entry: &str,
    fragment_entry: Option<&str>,
    buffers: &[wgpu::VertexBufferLayout<'_>],
    compare: Option<wgpu::CompareFunction>,
    cull_mode: Option<wgpu::Face>,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout(device, label, layouts)),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex_entry),
            compilation_options: Default::default(),
            buffers: &buffers.iter().cloned().map(Some).collect::<Vec<_>>(),
        },
        // Both sides unless told (occluders may be open meshes; volume faces are classified in
        // the shader).
        primitive: wgpu::PrimitiveState {
            cull_mode,
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

/// A fullscreen-triangle render pipeline (the prelude's `vs_fullscreen`) writing `format`.
pub(crate) fn fullscreen_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    fragment_entry: &str,
    format: wgpu::TextureFormat,
    constants: &[(&str, f64)],
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout(device, label, &[layout])),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_fullscreen"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some(fragment_entry),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                ..Default::default()
            },
            targets: &[Some(format.into())],
        }),
        multiview_mask: None,
        cache: None,
    })
}

#[cfg(test)]
mod tests {
    use crate::gpu::wgsl::{compose, Wgsl};
    use crate::gpu::ShaderPrecision;

    /// Parses and validates `source` with its imports; an error names the file and line it is
    /// in.
    fn check(source: &Wgsl<'_>, precision: ShaderPrecision) -> Result<(), String> {
        let composed = compose(source, precision);
        let text = &composed.text;
        let at = |location: Option<naga::SourceLocation>, message: String| {
            let line = location.map_or(0, |l| l.line_number as usize);
            let (file, line) = composed.locate(line);
            format!("{file}:{line}: {message}")
        };
        let module = naga::front::wgsl::parse_str(text)
            .map_err(|e| at(e.location(text), e.message().to_string()))?;
        naga::valid::Validator::new(Default::default(), naga::valid::Capabilities::all())
            .validate(&module)
            .map_err(|e| at(e.location(text), format!("{:?}", e.into_inner())))?;
        Ok(())
    }

    /// Every shader file under `shaders/` parses and validates at every precision, composed
    /// with its imports as a node composes it: the pass files (`passes/`), the self-contained
    /// `SHADOW_WGSL` (`public/`) and the shared files (`shared/`), the folders read when the test
    /// runs, so that no list of files can miss one (`precision.wgsl`, the wrappers every
    /// composition begins with, is checked by all).
    #[test]
    fn every_shader_compiles() {
        fn wgsl_under(dir: &std::path::Path, files: &mut Vec<std::path::PathBuf>) {
            for entry in std::fs::read_dir(dir).expect("a shaders folder") {
                let path = entry.expect("a folder entry").path();
                if path.is_dir() {
                    wgsl_under(&path, files);
                } else if path.extension().is_some_and(|e| e == "wgsl") {
                    files.push(path);
                }
            }
        }
        let folder = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
        let mut paths = Vec::new();
        for sub in ["passes", "public", "shared"] {
            wgsl_under(&folder.join(sub), &mut paths);
        }
        paths.sort();
        // The pass files and the shared ones, each a dozen or more, and the public one.
        assert!(paths.len() >= 23, "{paths:?}");
        // Nothing else in the folder but the precision wrappers.
        let mut top: Vec<String> = std::fs::read_dir(&folder)
            .expect("the shaders folder")
            .map(|entry| entry.expect("a folder entry").file_name())
            .filter_map(|name| name.into_string().ok())
            .collect();
        top.sort();
        assert_eq!(top, ["passes", "precision.wgsl", "public", "shared"]);
        for path in &paths {
            let text = std::fs::read_to_string(path).expect("a shader file");
            let name = path.strip_prefix(&folder).expect("under shaders/");
            let name = name.to_str().expect("a UTF-8 path");
            let source = Wgsl { name, text: &text };
            for precision in ShaderPrecision::ALL {
                if let Err(e) = check(&source, precision) {
                    panic!("{precision:?}: {e}");
                }
            }
        }
    }

    /// An error names the file and line it is in: in the node after an import of 500 lines,
    /// and in the imported file itself.
    #[test]
    fn errors_point_at_the_file_and_line() {
        let node = Wgsl {
            name: "node.wgsl",
            text:
                "#import pcss.wgsl\n// a node\nfn f() -> f32 {\n    let x = ;\n    return 1.0;\n}\n",
        };
        let e = check(&node, ShaderPrecision::Native).unwrap_err();
        assert!(e.starts_with("node.wgsl:4:"), "{e}");
        let importer = Wgsl {
            name: "importer.wgsl",
            text: "#import prelude.wgsl\n#import broken.wgsl\n",
        };
        let e = check(&importer, ShaderPrecision::Native).unwrap_err();
        assert!(e.starts_with("broken.wgsl:3:"), "{e}");
    }

    /// Each shared file declares what it reads (its imports, and pcss.wgsl its bind group): on
    /// its own it parses and validates.
    #[test]
    fn every_shared_file_compiles_on_its_own() {
        for file in crate::gpu::wgsl::FILES {
            let alone = Wgsl {
                name: "alone.wgsl",
                text: &format!("#import {}\n", file.name),
            };
            if let Err(e) = check(&alone, ShaderPrecision::Native) {
                panic!("{}: {e}", file.name);
            }
        }
    }
}
