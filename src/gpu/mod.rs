//! GPU plumbing shared by the nodes: the helpers that build pipelines and bind groups, shader
//! precision, occluder meshes, the pass timer, the checks on textures and buffers, and the
//! headless device and readback used by tests, examples and offline tools.

pub mod headless;
mod mesh;
pub(crate) mod passes;
pub(crate) mod pipeline;
pub(crate) mod precision;
pub(crate) mod scope;
mod timer;
pub(crate) mod wgsl;

pub use mesh::{Occluder, OccluderMesh};
pub use passes::{passes_recorded, PassCount};
pub use precision::{ErrorSign, ShaderPrecision};
pub use timer::{GpuTimer, PassTime};

use crate::error::{Error, Result};

/// The bytes a buffer holding a `T` binds: its size rounded up to 16. A WGSL struct's size is
/// rounded up to its alignment (16 with a vector or matrix member), so the Rust mirrors of the
/// parameter structs end at their last field and the buffer holds WGSL's trailing padding
/// (zeroed, never written). `nodes::layout` checks that nothing else differs.
pub(crate) const fn wgsl_size<T>() -> u64 {
    wgsl_size_of(std::mem::size_of::<T>())
}

/// [`wgsl_size`] of a struct of `bytes` bytes.
pub(crate) const fn wgsl_size_of(bytes: usize) -> u64 {
    (bytes as u64).next_multiple_of(16)
}

/// A node's per-frame parameters ("uniforms" in the shaders' sense), in a read-only storage
/// buffer (see `cache::Binding::Params` for why not a uniform buffer); skips the queue write
/// when the contents did not change.
pub(crate) struct UniformBuffer<T: bytemuck::Pod + PartialEq> {
    buffer: wgpu::Buffer,
    last: Option<T>,
}

impl<T: bytemuck::Pod + PartialEq> UniformBuffer<T> {
    pub(crate) fn new(device: &wgpu::Device, label: &str) -> Self {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: wgsl_size::<T>(),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Self { buffer, last: None }
    }

    /// Writes `value` unless it equals the last value written; returns whether it wrote.
    pub(crate) fn write(&mut self, queue: &wgpu::Queue, value: T) -> bool {
        if self.last == Some(value) {
            return false;
        }
        queue.write_buffer(&self.buffer, 0, bytemuck::bytes_of(&value));
        self.last = Some(value);
        true
    }

    /// The last value written.
    pub(crate) fn last(&self) -> Option<&T> {
        self.last.as_ref()
    }

    pub(crate) fn binding(&self) -> wgpu::BindingResource<'_> {
        self.buffer.as_entire_binding()
    }
}

/// Checks a depth texture the caller passes: a single-sampled 2D texture with a depth aspect
/// and `TEXTURE_BINDING` usage.
pub(crate) fn check_depth_texture(field: &'static str, texture: &wgpu::Texture) -> Result<()> {
    check_depth_layers(field, texture, 1)
}

/// Checks a depth texture with `layers` array layers (a shadow map).
pub(crate) fn check_depth_layers(
    field: &'static str,
    texture: &wgpu::Texture,
    layers: u32,
) -> Result<()> {
    let problem = |p: String| Err(Error::InvalidTexture { field, problem: p });
    let format = texture.format();
    if !format.has_depth_aspect() {
        return problem(format!("{format:?} has no depth aspect"));
    }
    if texture.depth_or_array_layers() != layers {
        return problem(format!(
            "has {} layers, expected {layers}",
            texture.depth_or_array_layers()
        ));
    }
    check_common(field, texture)
}

/// Checks a colour texture read with `textureLoad` as float: single-sampled, 2D,
/// `TEXTURE_BINDING`, a float sample type.
pub(crate) fn check_float_texture(field: &'static str, texture: &wgpu::Texture) -> Result<()> {
    let format = texture.format();
    match format.sample_type(None, None) {
        Some(wgpu::TextureSampleType::Float { .. }) if texture.depth_or_array_layers() == 1 => {
            check_common(field, texture)
        }
        _ => Err(Error::InvalidTexture {
            field,
            problem: format!("{format:?} cannot be read as float colour, or has several layers"),
        }),
    }
}

fn check_common(field: &'static str, texture: &wgpu::Texture) -> Result<()> {
    let problem = |p: String| Err(Error::InvalidTexture { field, problem: p });
    if texture.dimension() != wgpu::TextureDimension::D2 {
        return problem("must be a 2D texture".into());
    }
    if texture.sample_count() != 1 {
        return problem(format!(
            "must be single-sampled (resolve it first), has {} samples",
            texture.sample_count()
        ));
    }
    if !texture
        .usage()
        .contains(wgpu::TextureUsages::TEXTURE_BINDING)
    {
        return problem("needs TextureUsages::TEXTURE_BINDING".into());
    }
    Ok(())
}

/// Checks that `texture` is `width × height`.
pub(crate) fn check_size(
    field: &'static str,
    texture: &wgpu::Texture,
    width: u32,
    height: u32,
) -> Result<()> {
    if texture.width() != width || texture.height() != height {
        return Err(Error::InvalidTexture {
            field,
            problem: format!(
                "is {}x{}, expected {width}x{height}",
                texture.width(),
                texture.height()
            ),
        });
    }
    Ok(())
}

/// Checks that a storage buffer of `bytes` can be created and bound whole on `device`: a typed
/// error naming the exceeded limit, rather than a wgpu validation error behind `Ok`. Every
/// buffer the crate sizes from its inputs is checked by this or [`check_buffer_allocation`],
/// so a buffer beyond a device limit is always [`Error::DeviceLimitExceeded`].
pub(crate) fn check_buffer_size(
    device: &wgpu::Device,
    field: &'static str,
    bytes: u64,
) -> Result<()> {
    let limits = device.limits();
    check_limits(
        field,
        bytes,
        &[
            (
                "max_storage_buffer_binding_size",
                limits.max_storage_buffer_binding_size,
            ),
            ("max_buffer_size", limits.max_buffer_size),
        ],
    )
}

/// Checks that a buffer of `bytes` can be created on `device` (one bound a slot at a time, so
/// only its whole size is limited), as [`check_buffer_size`] does for buffers bound whole.
pub(crate) fn check_buffer_allocation(
    device: &wgpu::Device,
    field: &'static str,
    bytes: u64,
) -> Result<()> {
    check_limits(
        field,
        bytes,
        &[("max_buffer_size", device.limits().max_buffer_size)],
    )
}

/// [`Error::DeviceLimitExceeded`] for the first of `limits` that `bytes` exceeds.
fn check_limits(field: &'static str, bytes: u64, limits: &[(&'static str, u64)]) -> Result<()> {
    for &(limit, max) in limits {
        if bytes > max {
            return Err(Error::DeviceLimitExceeded {
                field,
                limit,
                needed: bytes,
                max,
            });
        }
    }
    Ok(())
}

/// A view of the depth aspect alone (depth-stencil formats cannot be sampled otherwise).
pub(crate) fn depth_view(texture: &wgpu::Texture) -> wgpu::TextureView {
    texture.create_view(&wgpu::TextureViewDescriptor {
        label: Some("volshadow depth view"),
        aspect: wgpu::TextureAspect::DepthOnly,
        ..Default::default()
    })
}

/// The depth aspect of a (shadow-map) texture as a 2D array view, every layer.
pub(crate) fn depth_array_view(texture: &wgpu::Texture) -> wgpu::TextureView {
    texture.create_view(&wgpu::TextureViewDescriptor {
        label: Some("volshadow shadow map array"),
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        aspect: wgpu::TextureAspect::DepthOnly,
        ..Default::default()
    })
}

/// Validates a pass size against the device's 2D texture limit.
pub(crate) fn check_target_size(
    field: &'static str,
    device: &wgpu::Device,
    width: u32,
    height: u32,
) -> Result<()> {
    let max = device.limits().max_texture_dimension_2d;
    if width == 0 || height == 0 || width > max || height > max {
        return Err(Error::InvalidSize {
            field,
            width,
            height,
            min: 1,
            max,
        });
    }
    Ok(())
}

/// A single-mip, single-sampled 2D texture (`size` = width, height, layers).
pub(crate) fn texture_2d(
    device: &wgpu::Device,
    label: &str,
    size: (u32, u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    texture(
        device,
        label,
        wgpu::TextureDimension::D2,
        size,
        format,
        usage,
    )
}

/// A single-mip 3D texture (a grid), `size` = (width, height, depth).
pub(crate) fn texture_3d(
    device: &wgpu::Device,
    label: &str,
    size: (u32, u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    texture(
        device,
        label,
        wgpu::TextureDimension::D3,
        size,
        format,
        usage,
    )
}

fn texture(
    device: &wgpu::Device,
    label: &str,
    dimension: wgpu::TextureDimension,
    size: (u32, u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: size.0,
            height: size.1,
            depth_or_array_layers: size.2,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension,
        format,
        usage,
        view_formats: &[],
    })
}
