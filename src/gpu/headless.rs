//! A headless device and texture readback, for tests, examples and offline tools.
//!
//! The render-graph nodes never submit; this helper does, because reading a result back is
//! what a test or an offline renderer is for.

use crate::error::{Error, Result};

/// A device and queue on the adapter chosen from the environment. Cloning is cheap (wgpu's
/// handles): the clones share the device.
#[derive(Clone)]
pub struct HeadlessGpu {
    /// The instance the adapter came from.
    pub instance: wgpu::Instance,
    /// The chosen adapter.
    pub adapter: wgpu::Adapter,
    /// A device with the core feature set plus whichever requested optional features exist.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
}

impl HeadlessGpu {
    /// A device with no optional features, see [`with_optional_features`](Self::with_optional_features).
    ///
    /// # Errors
    ///
    /// As [`with_optional_features`](Self::with_optional_features).
    pub fn new() -> Result<Self> {
        Self::with_optional_features(wgpu::Features::empty())
    }

    /// Picks an adapter and creates a device with the default limits and those of `wanted`
    /// that the adapter offers (never failing for a missing optional feature).
    ///
    /// Honours `WGPU_BACKEND` (e.g. `vulkan`) and `WGPU_ADAPTER_NAME` (a case-insensitive
    /// substring, e.g. `llvmpipe` for lavapipe). Without them it prefers a discrete GPU, then an
    /// integrated, virtual or software one. No adapter is an error that says how to install
    /// lavapipe, never a silent fallback.
    ///
    /// # Errors
    ///
    /// [`Error::NoAdapter`] when no adapter exists (it says how to install lavapipe) or none matches
    /// `WGPU_ADAPTER_NAME`, and [`Error::RequestDevice`] when the adapter refuses the device.
    pub fn with_optional_features(wanted: wgpu::Features) -> Result<Self> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if wgpu::Backends::from_env().is_none() {
            desc.backends = wgpu::Backends::all();
        }
        let instance = wgpu::Instance::new(desc);
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
        let names: Vec<String> = adapters
            .iter()
            .map(|a| {
                let i = a.get_info();
                format!("{} ({:?}, {:?})", i.name, i.backend, i.device_type)
            })
            .collect();
        let adapter = match std::env::var("WGPU_ADAPTER_NAME") {
            Ok(wanted_name) => {
                let wanted_name = wanted_name.to_lowercase();
                adapters
                    .into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&wanted_name))
                    .ok_or_else(|| {
                        Error::NoAdapter(format!(
                            "WGPU_ADAPTER_NAME={wanted_name:?} matches none of {names:?}"
                        ))
                    })?
            }
            Err(_) => {
                let rank = |t: wgpu::DeviceType| match t {
                    wgpu::DeviceType::DiscreteGpu => 0,
                    wgpu::DeviceType::IntegratedGpu => 1,
                    wgpu::DeviceType::VirtualGpu => 2,
                    wgpu::DeviceType::Cpu => 3,
                    wgpu::DeviceType::Other => 4,
                };
                adapters
                    .into_iter()
                    .min_by_key(|a| rank(a.get_info().device_type))
                    .ok_or_else(|| {
                        Error::NoAdapter(
                            "no adapter on any backend. On a machine without a GPU driver \
                             install lavapipe (Debian/Ubuntu: apt-get install -y \
                             mesa-vulkan-drivers)"
                                .into(),
                        )
                    })?
            }
        };
        let features = adapter.features() & wanted;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("volshadow headless"),
            required_features: features,
            required_limits: wgpu::Limits::default(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::RequestDevice(e.to_string()))?;
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
        })
    }

    /// The adapter's name, driver and backend in one line, for reports.
    pub fn adapter_summary(&self) -> String {
        let i = self.adapter.get_info();
        format!(
            "{} ({:?}, {:?}, driver {} {})",
            i.name, i.backend, i.device_type, i.driver, i.driver_info
        )
    }

    /// Submits `encoder` and waits for the GPU to finish it.
    ///
    /// # Errors
    ///
    /// [`Error::Readback`] when waiting for the device fails (e.g. the device was lost).
    pub fn submit_and_wait(&self, encoder: wgpu::CommandEncoder) -> Result<()> {
        self.queue.submit([encoder.finish()]);
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Readback(e.to_string()))?;
        Ok(())
    }

    /// Reads mip 0, layer 0 of a 2D texture (usage `COPY_SRC`; a colour format with a fixed
    /// block size, or `Depth32Float`) back as tightly packed rows of bytes.
    ///
    /// # Errors
    ///
    /// [`Error::Readback`] for a texture without `COPY_SRC`, a format without a fixed texel
    /// size for copies (compressed, or a depth format whose depth cannot be copied, such as
    /// `Depth24Plus`) and when waiting for the copy or mapping the buffer fails; each before
    /// anything is recorded, so no validation error is left behind.
    pub fn read_texture_bytes(&self, texture: &wgpu::Texture) -> Result<Vec<u8>> {
        self.read_layers(texture, 1)
    }

    /// As [`read_texture_bytes`](Self::read_texture_bytes), but every array layer of a 2D
    /// texture, or every depth slice of a 3D one, one after the other (layer 0 or the nearest
    /// slice first).
    ///
    /// # Errors
    ///
    /// Those of [`read_texture_bytes`](Self::read_texture_bytes), and
    /// [`Error::DeviceLimitExceeded`] naming `max_buffer_size` where the texture holds more
    /// bytes than this device's largest buffer.
    pub fn read_all_layers_bytes(&self, texture: &wgpu::Texture) -> Result<Vec<u8>> {
        self.read_layers(texture, texture.depth_or_array_layers())
    }

    /// Mip 0 of the first `layers` layers (or depth slices) of `texture`, tightly packed.
    fn read_layers(&self, texture: &wgpu::Texture, layers: u32) -> Result<Vec<u8>> {
        if !texture.usage().contains(wgpu::TextureUsages::COPY_SRC) {
            return Err(Error::Readback(format!(
                "the texture lacks TextureUsages::COPY_SRC (has {:?}): it cannot be copied out",
                texture.usage()
            )));
        }
        let format = texture.format();
        let aspect = if format.is_depth_stencil_format() {
            wgpu::TextureAspect::DepthOnly
        } else {
            wgpu::TextureAspect::All
        };
        let texel = format
            .block_copy_size(Some(aspect))
            .filter(|_| format.block_dimensions() == (1, 1))
            .ok_or_else(|| Error::Readback(format!("{format:?} cannot be read back")))?;
        let (width, height) = (texture.width(), texture.height());
        let row = width * texel;
        let padded =
            row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let size = u64::from(padded) * u64::from(height) * u64::from(layers);
        crate::gpu::check_buffer_allocation(&self.device, "readback", size)?;
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("volshadow readback"),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded),
                    rows_per_image: Some(height),
                },
            },
            wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: layers,
            },
        );
        let mapped = self.submit_and_map(encoder, &buffer)?;
        let rows = height as usize * layers as usize;
        let mut out = Vec::with_capacity(row as usize * rows);
        for y in 0..rows {
            let start = y * padded as usize;
            out.extend_from_slice(&mapped[start..start + row as usize]);
        }
        Ok(out)
    }

    /// Submits `encoder`, which copies into `buffer` (`MAP_READ`), and returns its contents.
    fn submit_and_map(
        &self,
        encoder: wgpu::CommandEncoder,
        buffer: &wgpu::Buffer,
    ) -> Result<Vec<u8>> {
        self.submit_and_wait(encoder)?;
        let slice = buffer.slice(..);
        let (sender, receiver) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = sender.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Readback(e.to_string()))?;
        receiver
            .recv()
            .map_err(|e| Error::Readback(e.to_string()))?
            .map_err(|e| Error::Readback(e.to_string()))?;
        let out = slice
            .get_mapped_range()
            .map_err(|e| Error::Readback(format!("{e:?}")))?
            .to_vec();
        buffer.unmap();
        Ok(out)
    }

    /// Reads a whole buffer (usage `COPY_SRC`, size a multiple of 4) back.
    ///
    /// # Errors
    ///
    /// [`Error::Readback`] for a buffer without `COPY_SRC` (before anything is recorded), and
    /// when waiting for the copy or mapping fails.
    pub fn read_buffer_bytes(&self, source: &wgpu::Buffer) -> Result<Vec<u8>> {
        if !source.usage().contains(wgpu::BufferUsages::COPY_SRC) {
            return Err(Error::Readback(format!(
                "the buffer lacks BufferUsages::COPY_SRC (has {:?}): it cannot be copied out",
                source.usage()
            )));
        }
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("volshadow readback"),
            size: source.size(),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(source, 0, &buffer, 0, source.size());
        self.submit_and_map(encoder, &buffer)
    }

    /// Reads an `Rgba32Float` texture back, row-major from the top row.
    ///
    /// # Errors
    ///
    /// [`Error::Readback`] for a texture that is not `Rgba32Float`, and those of
    /// [`read_texture_bytes`](Self::read_texture_bytes).
    pub fn read_rgba32f(&self, texture: &wgpu::Texture) -> Result<Vec<[f32; 4]>> {
        if texture.format() != wgpu::TextureFormat::Rgba32Float {
            return Err(Error::Readback(format!(
                "expected Rgba32Float, got {:?}",
                texture.format()
            )));
        }
        let bytes = self.read_texture_bytes(texture)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// Reads an `Rgba16Float` (the composite's default output) or `Rgba32Float` texture back
    /// as f32, row-major from the top row.
    ///
    /// # Errors
    ///
    /// [`Error::Readback`] for another format, and those of
    /// [`read_texture_bytes`](Self::read_texture_bytes).
    pub fn read_rgba(&self, texture: &wgpu::Texture) -> Result<Vec<[f32; 4]>> {
        match texture.format() {
            wgpu::TextureFormat::Rgba32Float => self.read_rgba32f(texture),
            wgpu::TextureFormat::Rgba16Float => {
                let bytes = self.read_texture_bytes(texture)?;
                let halves: Vec<half::f16> = bytemuck::pod_collect_to_vec(&bytes);
                Ok(halves
                    .chunks_exact(4)
                    .map(|c| [c[0].to_f32(), c[1].to_f32(), c[2].to_f32(), c[3].to_f32()])
                    .collect())
            }
            other => Err(Error::Readback(format!(
                "expected Rgba16Float or Rgba32Float, got {other:?}"
            ))),
        }
    }

    /// Reads an `Rgba16Float` or `Rgba32Float` texture back, tone-maps it ([`tone_map`]) and
    /// writes it to `path` as an 8-bit sRGB PNG.
    ///
    /// # Errors
    ///
    /// Those of [`read_rgba`](Self::read_rgba); [`Error::FileWrite`] when the file cannot be
    /// written.
    #[cfg(feature = "image")]
    pub fn save_png(
        &self,
        texture: &wgpu::Texture,
        path: &std::path::Path,
        exposure: f32,
    ) -> Result<()> {
        let pixels = self.read_rgba(texture)?;
        let rgba = tone_map(&pixels, exposure);
        image::save_buffer_with_format(
            path,
            &rgba,
            texture.width(),
            texture.height(),
            image::ColorType::Rgba8,
            image::ImageFormat::Png,
        )
        .map_err(|e| Error::FileWrite {
            path: path.display().to_string(),
            problem: e.to_string(),
        })
    }
}

/// Linear radiance to 8-bit sRGB for display: each channel times `exposure`, then Reinhard's
/// `v / (1 + v)` (so no value clips), then the sRGB curve; alpha 255. NaN, negative and
/// infinite values map to 0, 0 and 255. Returns `4 × pixels.len()` bytes (RGBA8, the
/// pixels' order).
pub fn tone_map(pixels: &[[f32; 4]], exposure: f32) -> Vec<u8> {
    let encode = |v: f32| {
        let v = exposure * v;
        let v = if v.is_nan() || v <= 0.0 {
            0.0
        } else if v.is_finite() {
            v / (1.0 + v)
        } else {
            1.0
        };
        let s = if v <= 0.003_130_8 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        };
        (s.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    };
    pixels
        .iter()
        .flat_map(|p| [encode(p[0]), encode(p[1]), encode(p[2]), 255])
        .collect()
}
