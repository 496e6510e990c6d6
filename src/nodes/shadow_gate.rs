//! The shadow map's gate: where the exact method counts shadow volumes, a light without a
//! radius needs its map only for the pixels whose crossings cannot be counted (a list that
//! overflowed, a face of an open or non-manifold mesh), which only the GPU knows. The map's
//! render passes then load their layer instead of clearing it and draw indirectly, from
//! arguments that are zero unless `shaders/passes/shadow_gate.wgsl` found such a pixel in this
//! frame's crossing lists and the map has not been drawn since its inputs last changed: a frame the
//! crossings decide draws nothing, clears nothing, and reads no texel of the map.

use crate::gpu::pipeline::{bind_group, compute_pipeline, dispatch, layout, module, Binding};
use crate::gpu::wgsl::wgsl_file;
use crate::gpu::{GpuTimer, ShaderPrecision};
use crate::nodes::Crossings;
use crate::pass::Pass;

/// The binding table: `@binding(i)` of `shaders/passes/shadow_gate.wgsl` is entry `i`.
const BINDINGS: [Binding; 5] = [
    Binding::Params,    // heads: the crossing lists' heads
    Binding::Params,    // template: the map's draw arguments
    Binding::Params,    // gp: GateUniform
    Binding::ReadWrite, // gate: drawn since the inputs changed, drawn this frame
    Binding::ReadWrite, // live: the arguments the draws read
];

/// Invocations per workgroup of `scan` (one pixel each).
const WORKGROUP: u32 = 256;

/// Words of a non-indexed indirect draw's arguments (the clear) and an indexed one's.
const CLEAR_WORDS: usize = 4;
const DRAW_WORDS: usize = 5;

/// WGSL `GateParams` of `shaders/passes/shadow_gate.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GateUniform {
    pixels: u32,
    entries: u32,
    words: u32,
    pad: u32,
}

/// The gate's layout and pipeline, held by the [`Cache`](crate::nodes::Cache) with the shadow
/// map's.
#[derive(Clone)]
pub(crate) struct GatePipelines {
    layout: wgpu::BindGroupLayout,
    scan: wgpu::ComputePipeline,
}

impl GatePipelines {
    pub(crate) fn new(device: &wgpu::Device, precision: ShaderPrecision) -> Self {
        let label = "volshadow shadow gate";
        let layout = layout(device, label, wgpu::ShaderStages::COMPUTE, &BINDINGS);
        let scan = compute_pipeline(
            device,
            label,
            &[&layout],
            &module(device, &wgsl_file!("shadow_gate.wgsl"), precision),
            "scan",
            &[],
        );
        Self { layout, scan }
    }
}

/// Where one layer's draws find their arguments in the gate's buffer (byte offsets).
pub(crate) struct LayerArgs {
    /// The layer.
    pub layer: u32,
    /// Its clear: a triangle over the layer at depth 0.
    pub clear: u64,
    /// Its occluders' draws: the draw's index (into the node's draws) and its arguments.
    pub draws: Vec<(u32, u64)>,
}

/// One layer's draws for [`arguments`]: the layer, and per draw `(draw, count, instances)`.
pub(crate) type LayerDraws = (u32, Vec<(u32, u32, u32)>);

/// The draw arguments of a gated map: per recorded layer its clear, then its occluders' draws
/// `(draw, count, instances)`: indexed (`count` indices, one instance), or for a clipped
/// occluder non-indexed (`count` vertices, `instances` fan triangles each).
pub(crate) fn arguments(layers: &[LayerDraws]) -> (Vec<u32>, Vec<LayerArgs>) {
    let mut words = Vec::new();
    let mut placed = Vec::new();
    for (layer, draws) in layers {
        let clear = 4 * words.len() as u64;
        words.extend([3, 1, 0, 0]);
        let mut at = Vec::new();
        for &(draw, count, instances) in draws {
            at.push((draw, 4 * words.len() as u64));
            if instances == 1 {
                words.extend([count, 1, 0, 0, 0]);
            } else {
                // A clipped occluder's non-indexed draw (`vs_shadow_clipped`).
                words.extend([count, instances, 0, 0]);
            }
        }
        placed.push(LayerArgs {
            layer: *layer,
            clear,
            draws: at,
        });
    }
    debug_assert_eq!(
        words.len(),
        layers
            .iter()
            .map(|(_, draws)| CLEAR_WORDS
                + draws
                    .iter()
                    .map(|d| if d.2 == 1 { DRAW_WORDS } else { CLEAR_WORDS })
                    .sum::<usize>())
            .sum::<usize>()
    );
    (words, placed)
}

/// The gate of one shadow map (see the module docs).
pub(crate) struct Gate {
    pipelines: GatePipelines,
    /// Two words: the map was drawn since its inputs last changed; this frame draws it.
    state: wgpu::Buffer,
    params: wgpu::Buffer,
    /// The arguments the CPU writes, and the ones the draws read (zero unless the gate opens).
    template: Option<wgpu::Buffer>,
    live: Option<wgpu::Buffer>,
    words: u32,
    /// The heads buffer `bind_group` reads.
    heads: Option<wgpu::Buffer>,
    bind_group: Option<wgpu::BindGroup>,
    groups: (u32, u32),
    /// Where each recorded layer's draws find their arguments.
    pub layers: Vec<LayerArgs>,
    /// The map's inputs changed: the next encode forgets that it was drawn.
    reset: bool,
}

impl Gate {
    pub(crate) fn new(device: &wgpu::Device, pipelines: &GatePipelines) -> Self {
        let buffer = |label, size, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        Self {
            pipelines: pipelines.clone(),
            state: buffer(
                "volshadow shadow gate",
                8,
                U::STORAGE | U::COPY_DST | U::COPY_SRC,
            ),
            params: buffer("volshadow shadow gate params", 16, U::STORAGE | U::COPY_DST),
            template: None,
            live: None,
            words: 0,
            heads: None,
            bind_group: None,
            groups: (0, 0),
            layers: Vec::new(),
            reset: true,
        }
    }

    /// New draw arguments (the map's inputs changed): the map is drawn again when next needed.
    pub(crate) fn set_arguments(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        (words, layers): (Vec<u32>, Vec<LayerArgs>),
    ) {
        let size = (4 * words.len().max(1)) as u64;
        if self.template.as_ref().is_none_or(|b| b.size() < size) {
            use wgpu::BufferUsages as U;
            let buffer = |label, usage| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage,
                    mapped_at_creation: false,
                })
            };
            self.template = Some(buffer(
                "volshadow shadow gate arguments",
                U::STORAGE | U::COPY_DST,
            ));
            self.live = Some(buffer(
                "volshadow shadow gate live arguments",
                U::STORAGE | U::INDIRECT | U::COPY_DST,
            ));
            self.bind_group = None;
        }
        if !words.is_empty() {
            let template = self.template.as_ref().expect("just sized");
            queue.write_buffer(template, 0, bytemuck::cast_slice(&words));
        }
        self.words = words.len() as u32;
        self.layers = layers;
        self.reset = true;
    }

    /// Binds this frame's crossing lists.
    pub(crate) fn bind(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, c: &Crossings<'_>) {
        if self.heads.as_ref() != Some(c.heads) {
            self.bind_group = None;
        }
        let pixels = c.size.0 * c.size.1;
        let params = GateUniform {
            pixels,
            entries: c.per_pixel,
            words: self.words,
            pad: 0,
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let groups = pixels.div_ceil(WORKGROUP).max(1);
        let x = groups.min(device.limits().max_compute_workgroups_per_dimension);
        self.groups = (x, groups.div_ceil(x));
        if self.bind_group.is_none() {
            let (Some(template), Some(live)) = (&self.template, &self.live) else {
                return;
            };
            self.bind_group = Some(bind_group(
                device,
                "volshadow shadow gate",
                &self.pipelines.layout,
                [
                    c.heads.as_entire_binding(),
                    template.as_entire_binding(),
                    self.params.as_entire_binding(),
                    self.state.as_entire_binding(),
                    live.as_entire_binding(),
                ],
            ));
            self.heads = Some(c.heads.clone());
        }
    }

    /// The arguments the map's draws read.
    pub(crate) fn live(&self) -> Option<&wgpu::Buffer> {
        self.live.as_ref()
    }

    /// Two `u32`: whether the map was drawn since its inputs last changed, and whether the last
    /// recorded frame drew it.
    pub(crate) fn state(&self) -> &wgpu::Buffer {
        &self.state
    }

    /// Records the scan: zeroes the live arguments (and, after new inputs, the drawn flag), then
    /// opens the gate if a pixel needs the map. Before the map's render passes.
    pub(crate) fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        timer: Option<&mut GpuTimer>,
    ) {
        let (Some(live), Some(group)) = (&self.live, &self.bind_group) else {
            return;
        };
        if std::mem::take(&mut self.reset) {
            encoder.clear_buffer(&self.state, 0, None);
        } else {
            encoder.clear_buffer(&self.state, 4, Some(4));
        }
        encoder.clear_buffer(live, 0, Some(4 * u64::from(self.words.max(1))));
        let (x, y) = self.groups;
        dispatch(
            encoder,
            timer,
            Pass::ShadowMap,
            "volshadow shadow gate",
            &[(&self.pipelines.scan, &[group], (x, y, 1))],
        );
    }
}
