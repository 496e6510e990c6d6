//! A spot light's projected texture (stained glass, gobo): linear RGB texels on the CPU.
//!
//! A textured spot light emits `intensity × texel(uv)` towards a point X, where uv is X seen
//! through the spot's texture frame ([`SpotLight::texture_frame`]):
//!
//! ```text
//! (x, y, z) = view · X,  t = tan(cone_angle / 2)
//! uv = (0.5 + 0.5 · x / (−z · t),  0.5 − 0.5 · y / (−z · t))      (v = 0 is the top row)
//! ```
//!
//! looked up bilinearly between texel centres, clamped to the edge. The texture covers the
//! square around the cone; its corners lie outside the cone and are never seen.

use glam::{Mat4, Vec3};

use crate::error::{Error, Result};
use crate::scene::SpotLight;

/// Which channels of a spot's GPU texture ([`FrameLight::texture`](crate::FrameLight::texture))
/// are its emission's multipliers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum TextureChannels {
    /// Red, green and blue: a coloured texture (stained glass).
    #[default]
    Rgb,
    /// The red channel alone, as a grey mask for every colour (a gobo; Bevy's
    /// `SpotLightTexture` convention). Green, blue and alpha are ignored.
    Red,
}

/// Linear RGB texels, row-major from the top row.
#[derive(Debug, Clone, PartialEq)]
pub struct LightTexture {
    width: u32,
    height: u32,
    texels: Vec<Vec3>,
}

impl LightTexture {
    /// Largest width or height accepted.
    pub const MAX_SIZE: u32 = 8192;

    /// Largest texel component: the largest finite `f16`, the format the texels upload in.
    pub const MAX_TEXEL: f32 = 65504.0;

    /// A texture of `width × height` texels (row-major, top row first; finite, ≥ 0, at most
    /// [`MAX_TEXEL`](Self::MAX_TEXEL), which uploads as `f16` infinity beyond).
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] unless both sides are in `1..=MAX_SIZE`, [`Error::InvalidTexture`] when
    /// `texels.len()` is not `width × height`, [`Error::NonFinite`], [`Error::Negative`] or
    /// [`Error::TexelOutOfRange`] for a bad texel.
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>) -> Result<Self> {
        if width == 0 || height == 0 || width > Self::MAX_SIZE || height > Self::MAX_SIZE {
            return Err(Error::InvalidSize {
                field: "light texture",
                width,
                height,
                min: 1,
                max: Self::MAX_SIZE,
            });
        }
        if texels.len() != (width as usize) * (height as usize) {
            return Err(Error::InvalidTexture {
                field: "light texture",
                problem: format!("{} texels for {width}x{height}", texels.len()),
            });
        }
        for (i, t) in texels.iter().enumerate() {
            crate::error::non_negative("light texture texel", &t.to_array())?;
            if t.max_element() > Self::MAX_TEXEL {
                return Err(Error::TexelOutOfRange {
                    texel: i,
                    value: t.max_element(),
                });
            }
        }
        Ok(Self {
            width,
            height,
            texels,
        })
    }

    /// A `cells × cells` checkerboard of two colours, `size × size` texels.
    ///
    /// # Errors
    ///
    /// [`Error::InvalidSize`] unless `1 <= size <= MAX_SIZE`, [`Error::InvalidSetting`]
    /// naming `checkerboard.cells` unless `1 <= cells <= size` (as a scene file's checkerboard),
    /// or a non-finite or negative colour (as [`LightTexture::new`]).
    pub fn checkerboard(size: u32, cells: u32, a: Vec3, b: Vec3) -> Result<Self> {
        if size == 0 || size > Self::MAX_SIZE {
            return Err(Error::InvalidSize {
                field: "light texture",
                width: size,
                height: size,
                min: 1,
                max: Self::MAX_SIZE,
            });
        }
        if cells == 0 || cells > size {
            return Err(Error::InvalidSetting {
                field: "checkerboard.cells",
                problem: format!("must be in 1..={size} (the texture size), got {cells}"),
            });
        }
        let texels = (0..size * size)
            .map(|i| {
                let (x, y) = (i % size, i / size);
                let (x, y, cells, size) = (
                    u64::from(x),
                    u64::from(y),
                    u64::from(cells),
                    u64::from(size),
                );
                if ((x * cells / size) + (y * cells / size)).is_multiple_of(2) {
                    a
                } else {
                    b
                }
            })
            .collect();
        Self::new(size, size, texels)
    }

    /// Loads an image file (PNG) as sRGB-encoded colour and converts it to linear RGB, with
    /// the default [`LoadOptions`](crate::load::LoadOptions).
    ///
    /// # Errors
    ///
    /// Those of [`from_image_file_with`](Self::from_image_file_with).
    #[cfg(feature = "image")]
    pub fn from_image_file(path: impl AsRef<std::path::Path>) -> Result<Self> {
        Self::from_image_file_with(path, &crate::load::LoadOptions::default())
    }

    /// [`from_image_file`](Self::from_image_file) with the bounds of `options`: the path must
    /// be a regular file of at most [`max_file_bytes`](crate::load::LoadOptions::max_file_bytes),
    /// and the image at most [`max_texels`](crate::load::LoadOptions::max_texels) texels and
    /// [`MAX_SIZE`](Self::MAX_SIZE) on a side, checked from its header before decoding.
    #[cfg(feature = "image")]
    pub fn from_image_file_with(
        path: impl AsRef<std::path::Path>,
        options: &crate::load::LoadOptions,
    ) -> Result<Self> {
        let path = path.as_ref();
        let mut budget = crate::load::Budget::new(options);
        let bytes = budget.read(path)?;
        Self::from_image_bytes(&bytes, &path.display().to_string(), &mut budget)
    }

    /// Decodes an encoded image (`label` names it in errors), counting its texels into
    /// `budget` before decoding.
    #[cfg(feature = "image")]
    pub(crate) fn from_image_bytes(
        bytes: &[u8],
        label: &str,
        budget: &mut crate::load::Budget,
    ) -> Result<Self> {
        use image::ImageDecoder;
        let invalid = |e: image::ImageError| Error::InvalidTexture {
            field: "light texture file",
            problem: format!("{label}: {e}"),
        };
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| Error::InvalidTexture {
                field: "light texture file",
                problem: format!("{label}: {e}"),
            })?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(Self::MAX_SIZE);
        limits.max_image_height = Some(Self::MAX_SIZE);
        reader.limits(limits);
        let decoder = reader.into_decoder().map_err(invalid)?;
        let (width, height) = decoder.dimensions();
        if width == 0 || height == 0 || width > Self::MAX_SIZE || height > Self::MAX_SIZE {
            return Err(Error::InvalidSize {
                field: "light texture",
                width,
                height,
                min: 1,
                max: Self::MAX_SIZE,
            });
        }
        budget.add(
            crate::load::Limit::Texels,
            u64::from(width) * u64::from(height),
            label,
        )?;
        let image = image::DynamicImage::from_decoder(decoder)
            .map_err(invalid)?
            .to_rgb8();
        let decode = |c: u8| {
            let c = f32::from(c) / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        };
        let texels = image
            .pixels()
            .map(|p| Vec3::new(decode(p[0]), decode(p[1]), decode(p[2])))
            .collect();
        Self::new(image.width(), image.height(), texels)
    }

    /// Width in texels.
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in texels.
    pub fn height(&self) -> u32 {
        self.height
    }
    /// The texels, row-major from the top row.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// Uploads the texels as an `Rgba16Float` texture (`TEXTURE_BINDING | COPY_DST`), one mip
    /// level: what the march's light-texture input expects.
    pub fn upload(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> wgpu::Texture {
        let size = wgpu::Extent3d {
            width: self.width,
            height: self.height,
            depth_or_array_layers: 1,
        };
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("volshadow light texture"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba16Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let data: Vec<half::f16> = self
            .texels
            .iter()
            .flat_map(|t| [t.x, t.y, t.z, 1.0])
            .map(half::f16::from_f32)
            .collect();
        queue.write_texture(
            texture.as_image_copy(),
            bytemuck::cast_slice(&data),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(self.width * 8),
                rows_per_image: Some(self.height),
            },
            size,
        );
        texture
    }
}

impl SpotLight {
    /// The spot's texture frame: a view matrix looking along the cone's axis from the light,
    /// with the up hint of [`with_texture_up`](SpotLight::with_texture_up), or else +Y (+X
    /// when the axis is within ~25° of vertical). See [`LightTexture`].
    pub fn texture_frame(&self) -> Mat4 {
        let dir = self.direction();
        let up = self
            .texture_up()
            .unwrap_or(if dir.y.abs() < 0.9 { Vec3::Y } else { Vec3::X });
        glam::camera::rh::view::look_to_mat4(self.position(), dir, up)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `cells: 0` was made one cell silently (and `cells > size` cells narrower than a texel),
    /// where a scene file's checkerboard refuses both: now a typed error naming the field.
    #[test]
    fn checkerboard_cells_out_of_range_is_an_error() {
        for (size, cells) in [(8, 0), (8, 9), (1, 2)] {
            match LightTexture::checkerboard(size, cells, Vec3::ONE, Vec3::ZERO) {
                Err(Error::InvalidSetting { field, problem }) => {
                    assert_eq!(field, "checkerboard.cells");
                    assert!(problem.contains(&format!("got {cells}")), "{problem}");
                }
                other => panic!("{size}, {cells}: {other:?}"),
            }
        }
        for (size, cells) in [(8, 1), (8, 8), (1, 1)] {
            let t = LightTexture::checkerboard(size, cells, Vec3::ONE, Vec3::ZERO).unwrap();
            assert_eq!((t.width, t.height), (size, size));
        }
    }
}
