//! What the march counts: the exact method's list statistics ([`MarchStats`]) and the per-pixel
//! work counters ([`MarchWork`]), read back from its stats buffer.

/// What the exact method met in a frame, counted by the march (see
/// [`MarchNode::stats_buffer`](crate::nodes::MarchNode::stats_buffer)).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MarchStats {
    /// Pixels whose crossing list overflowed (marched between their nearest and farthest
    /// crossing instead).
    pub overflowed: u32,
    /// Pixels whose list was more than half full (counted only for those, so that the common
    /// case does not contend on one counter).
    pub crowded: u32,
    /// The most crossings one of those pixels had (0 when no list was more than half full).
    pub max_crossings: u32,
}

impl MarchStats {
    /// Decodes the bytes of [`MarchNode::stats_buffer`](crate::nodes::MarchNode::stats_buffer)
    /// (four `u32` in the platform's byte order, the last unused).
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        let words: &[u32] = bytemuck::try_cast_slice(bytes.get(..16)?).ok()?;
        Some(Self {
            overflowed: words[0],
            crowded: words[1],
            max_crossings: words[2],
        })
    }
}

/// A march's per-pixel work counters (see
/// [`MarchNode::set_work_counters`](crate::nodes::MarchNode::set_work_counters)), one entry per
/// pixel in row-major order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MarchWork {
    /// Shadow-map visibility queries (each one filtered lookup, whatever its taps).
    pub lookups: Vec<u32>,
    /// Light-texture reads (a textured spot): its samples and the cells of its flat-region map
    /// ([`LightTextureNode::flats`](crate::nodes::LightTextureNode::flats)) the march reads.
    pub texture_samples: Vec<u32>,
    /// Crossing-list entries read (the exact method walks its list once per interval).
    pub crossings_visited: Vec<u32>,
    /// Crossing-list entries stored for the pixel (in front of its surface, at most the
    /// list's length).
    pub crossings_stored: Vec<u32>,
}

impl MarchWork {
    /// Decodes the bytes of a [`MarchNode::stats_buffer`](crate::nodes::MarchNode::stats_buffer)
    /// written with work counters on (`u32` in the platform's byte order); `None` when they hold no
    /// counters.
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        let words: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|c| u32::from_ne_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let pixels = words.get(4..)?;
        if pixels.is_empty() {
            return None;
        }
        let column = |k: usize| pixels.chunks_exact(4).map(|p| p[k]).collect();
        Some(Self {
            lookups: column(0),
            texture_samples: column(1),
            crossings_visited: column(2),
            crossings_stored: column(3),
        })
    }
}

/// A march's stats buffer of `size` bytes.
pub(super) fn stats_buffer(device: &wgpu::Device, size: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("volshadow march stats"),
        size,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}
