//! Per-pass GPU times through timestamp queries, when the device has them.
//!
//! Timestamp queries are an optional feature (`Features::TIMESTAMP_QUERY`). Without it a
//! [`GpuTimer`] records nothing and [`GpuTimer::read`] returns no passes: time the whole
//! submission with the wall clock instead (see `HeadlessGpu::submit_and_wait`).
//!
//! lavapipe offers the feature, but its timestamps do not bracket compute dispatches (a
//! 512×512 march read 0.02 ms in a 270 ms submission; render passes read plausibly). On a CPU
//! adapter, time passes by submitting each alone
//! ([`VolumetricShadows::encode_step`](crate::VolumetricShadows::encode_step)), as the
//! `report` example does.

use crate::error::{Error, Result};
use crate::pass::Pass;

/// Collects begin/end timestamps of the passes that nodes record with it.
pub struct GpuTimer {
    queries: Option<Queries>,
    passes: Vec<(Pass, Option<usize>)>,
    /// The light the passes recorded next serve (set by the facade per step).
    pub(crate) light: Option<usize>,
    capacity: u32,
}

struct Queries {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    period_ns: f64,
}

/// One pass's GPU time.
#[derive(Debug, Clone, PartialEq)]
pub struct PassTime {
    /// The pass.
    pub pass: Pass,
    /// The light it served (`None`: the whole frame, or a node timed on its own).
    pub light: Option<usize>,
    /// GPU time in milliseconds.
    pub ms: f64,
}

impl GpuTimer {
    /// A timer for up to `max_passes` passes per frame. Uses timestamp queries if `device` was
    /// created with `Features::TIMESTAMP_QUERY`, else records nothing.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, max_passes: u32) -> Self {
        let capacity = max_passes.clamp(1, 2048);
        let queries = device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
            .then(|| {
                let bytes = u64::from(capacity) * 2 * 8;
                Queries {
                    set: device.create_query_set(&wgpu::QuerySetDescriptor {
                        label: Some("volshadow timestamps"),
                        ty: wgpu::QueryType::Timestamp,
                        count: capacity * 2,
                    }),
                    resolve: device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("volshadow timestamp resolve"),
                        size: bytes,
                        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                        mapped_at_creation: false,
                    }),
                    readback: device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("volshadow timestamp readback"),
                        size: bytes,
                        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                        mapped_at_creation: false,
                    }),
                    period_ns: f64::from(queue.get_timestamp_period()),
                }
            });
        Self {
            queries,
            passes: Vec::new(),
            light: None,
            capacity,
        }
    }

    /// Whether passes are timed on the GPU.
    pub fn is_timing(&self) -> bool {
        self.queries.is_some()
    }

    /// Forgets the passes of the previous frame.
    pub fn clear(&mut self) {
        self.passes.clear();
    }

    fn next_pair(&mut self, pass: Pass) -> Option<(&wgpu::QuerySet, u32)> {
        let index = self.passes.len() as u32;
        if index >= self.capacity {
            return None;
        }
        let queries = self.queries.as_ref()?;
        self.passes.push((pass, self.light));
        Some((&queries.set, index * 2))
    }

    /// Timestamp writes for a compute pass of `pass` (None when not timing or full).
    pub fn compute_pass(&mut self, pass: Pass) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.next_pair(pass)
            .map(|(set, i)| wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(i),
                end_of_pass_write_index: Some(i + 1),
            })
    }

    /// Timestamp writes for a render pass of `pass` (None when not timing or full).
    pub fn render_pass(&mut self, pass: Pass) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        self.next_pair(pass)
            .map(|(set, i)| wgpu::RenderPassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(i),
                end_of_pass_write_index: Some(i + 1),
            })
    }

    /// Records the resolve of this frame's timestamps; call after the timed passes, before
    /// submitting.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        let Some(q) = &self.queries else { return };
        let count = self.passes.len() as u32 * 2;
        if count == 0 {
            return;
        }
        encoder.resolve_query_set(&q.set, 0..count, &q.resolve, 0);
        encoder.copy_buffer_to_buffer(&q.resolve, 0, &q.readback, 0, u64::from(count) * 8);
    }

    /// Reads the times back after the submission that contains [`resolve`](Self::resolve) (blocks
    /// until the GPU is done). Times of the same pass and light are summed, in first-seen order.
    ///
    /// # Errors
    ///
    /// [`Error::Readback`] when mapping the query buffer or waiting for the device fails.
    pub fn read(&self, device: &wgpu::Device) -> Result<Vec<PassTime>> {
        let Some(q) = &self.queries else {
            return Ok(Vec::new());
        };
        let count = self.passes.len() as u64 * 2;
        if count == 0 {
            return Ok(Vec::new());
        }
        let slice = q.readback.slice(..count * 8);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = sender.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Readback(e.to_string()))?;
        receiver
            .recv()
            .map_err(|e| Error::Readback(e.to_string()))?
            .map_err(|e| Error::Readback(e.to_string()))?;
        let ticks: Vec<u64> = {
            let mapped = slice
                .get_mapped_range()
                .map_err(|e| Error::Readback(format!("{e:?}")))?;
            bytemuck::pod_collect_to_vec(&mapped)
        };
        q.readback.unmap();
        let mut out: Vec<PassTime> = Vec::new();
        for (i, &(pass, light)) in self.passes.iter().enumerate() {
            let ms = ticks[2 * i + 1].saturating_sub(ticks[2 * i]) as f64 * q.period_ns * 1e-6;
            match out.iter_mut().find(|p| (p.pass, p.light) == (pass, light)) {
                Some(p) => p.ms += ms,
                None => out.push(PassTime { pass, light, ms }),
            }
        }
        Ok(out)
    }
}
