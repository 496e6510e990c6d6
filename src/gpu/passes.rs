//! Counts the render and compute passes volshadow records, per thread: the work counters of
//! benches and tests ([`passes_recorded`]). Every pass a node records begins here.

use std::cell::Cell;

thread_local! {
    static RECORDED: Cell<PassCount> = const { Cell::new(PassCount { render: 0, compute: 0 }) };
}

/// Render and compute passes recorded (see [`passes_recorded`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PassCount {
    /// Render passes.
    pub render: u64,
    /// Compute passes.
    pub compute: u64,
}

impl std::ops::Sub for PassCount {
    type Output = PassCount;
    fn sub(self, earlier: PassCount) -> PassCount {
        PassCount {
            render: self.render - earlier.render,
            compute: self.compute - earlier.compute,
        }
    }
}

/// The render and compute passes volshadow's nodes have recorded on this thread since it
/// started (into any encoder, submitted or not): subtract two readings to count a frame's.
pub fn passes_recorded() -> PassCount {
    RECORDED.with(Cell::get)
}

/// Adds a pass to this thread's count.
fn count(add: fn(&mut PassCount)) {
    RECORDED.with(|c| {
        let mut n = c.get();
        add(&mut n);
        c.set(n);
    });
}

/// Begins a render pass, counted.
pub(crate) fn begin_render<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    descriptor: &wgpu::RenderPassDescriptor<'_>,
) -> wgpu::RenderPass<'e> {
    count(|n| n.render += 1);
    encoder.begin_render_pass(descriptor)
}

/// Begins a render pass in an encoder of the crate's own that is finished and dropped, never
/// submitted (a check of the caller's texture, see `CompositeNode::check_output`): no work,
/// so not counted.
pub(crate) fn begin_unsubmitted_render<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    descriptor: &wgpu::RenderPassDescriptor<'_>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(descriptor)
}

/// Begins a compute pass, counted.
pub(crate) fn begin_compute<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    descriptor: &wgpu::ComputePassDescriptor<'_>,
) -> wgpu::ComputePass<'e> {
    count(|n| n.compute += 1);
    encoder.begin_compute_pass(descriptor)
}
