//! `HeadlessGpu`'s readback and PNG helpers (issue 36): an `Rgba16Float` output read back as
//! the values written, `tone_map`'s curve at known points, and `save_png` writing exactly the
//! tone-mapped bytes.

use volshadow::{tone_map, Error};

fn texture(
    gpu: &volshadow::HeadlessGpu,
    format: wgpu::TextureFormat,
    bytes: &[u8],
) -> wgpu::Texture {
    let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("readback test"),
        size: wgpu::Extent3d {
            width: 2,
            height: 2,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let texel = format.block_copy_size(None).unwrap();
    gpu.queue.write_texture(
        texture.as_image_copy(),
        bytes,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(2 * texel),
            rows_per_image: None,
        },
        wgpu::Extent3d {
            width: 2,
            height: 2,
            depth_or_array_layers: 1,
        },
    );
    texture
}

/// Four texels: values that f16 holds exactly, a large one, a negative one.
const VALUES: [[f32; 4]; 4] = [
    [0.0, 0.5, 1.0, 1.0],
    [3.0, 0.25, 2048.0, 1.0],
    [-1.0, 0.125, 7.0, 0.0],
    [1.5, 6.0, 0.75, 0.5],
];

#[test]
fn rgba16f_and_rgba32f_read_back_as_written() {
    let gpu = volshadow_harness::gpu();
    let halves: Vec<half::f16> = VALUES
        .iter()
        .flatten()
        .map(|&v| half::f16::from_f32(v))
        .collect();
    let t16 = texture(
        &gpu,
        wgpu::TextureFormat::Rgba16Float,
        bytemuck::cast_slice(&halves),
    );
    assert_eq!(gpu.read_rgba(&t16).unwrap(), VALUES.to_vec());
    let t32 = texture(
        &gpu,
        wgpu::TextureFormat::Rgba32Float,
        bytemuck::cast_slice(&VALUES),
    );
    assert_eq!(gpu.read_rgba(&t32).unwrap(), VALUES.to_vec());
    let r8 = texture(&gpu, wgpu::TextureFormat::Rgba8Unorm, &[0; 16]);
    assert!(matches!(gpu.read_rgba(&r8), Err(Error::Readback(_))));
}

#[test]
fn tone_map_follows_reinhard_and_srgb() {
    // 3 → Reinhard 0.75 → sRGB 1.055·0.75^(1/2.4) − 0.055 = 0.8809 → 225; 1/3 → 0.25 →
    // 0.5371 → 137; 9 → 0.9 → 0.9532 → 243; 0, negative and NaN → 0; ∞ → 255; alpha 255.
    let out = tone_map(
        &[
            [3.0, 0.0, -2.0, 0.0],
            [f32::INFINITY, f32::NAN, 1.0 / 3.0, 9.0],
        ],
        1.0,
    );
    assert_eq!(out, vec![225, 0, 0, 255, 255, 0, 137, 255]);
    let exposed = tone_map(&[[1.0 / 3.0, 1.0, 0.0, 0.0]], 9.0);
    assert_eq!(exposed, vec![225, 243, 0, 255]);
}

#[cfg(feature = "image")]
#[test]
fn save_png_writes_the_tone_mapped_bytes() {
    let gpu = volshadow_harness::gpu();
    let t32 = texture(
        &gpu,
        wgpu::TextureFormat::Rgba32Float,
        bytemuck::cast_slice(&VALUES),
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.png");
    gpu.save_png(&t32, &path, 1.5).unwrap();
    let png = image::open(&path).unwrap().to_rgba8();
    assert_eq!((png.width(), png.height()), (2, 2));
    assert_eq!(png.into_raw(), tone_map(&VALUES, 1.5));
    // A folder that does not exist: a typed error naming the path, not a panic.
    let missing = dir.path().join("no/such/folder/out.png");
    match gpu.save_png(&t32, &missing, 1.0) {
        Err(Error::FileWrite { path, .. }) => assert!(path.contains("no/such/folder")),
        other => panic!("expected FileWrite, got {other:?}"),
    }
}
