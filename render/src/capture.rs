//! Reading frames back from the GPU and writing them as PNG (display) or EXR (linear).

use crate::RenderError;
use std::path::Path;

/// A rendered frame on the CPU.
#[derive(Clone, Debug)]
pub struct CapturedFrame {
    pub width: u32,
    pub height: u32,
    /// Linear radiance, row-major from the top, RGBA.
    pub hdr: Vec<[f32; 4]>,
    /// Tone-mapped sRGB, RGBA8.
    pub ldr: Vec<[u8; 4]>,
}

/// Copies a texture into a mappable buffer and returns its rows without padding.
pub(crate) fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    bytes_per_pixel: u32,
) -> Result<Vec<u8>, RenderError> {
    let (width, height) = (texture.width(), texture.height());
    let unpadded = width * bytes_per_pixel;
    let padded = unpadded.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: (padded * height) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(height),
            },
        },
        wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
    );
    queue.submit(Some(encoder.finish()));
    read_mapped(device, &buffer, |data| {
        let mut out = Vec::with_capacity((unpadded * height) as usize);
        for row in 0..height {
            let start = (row * padded) as usize;
            out.extend_from_slice(&data[start..start + unpadded as usize]);
        }
        out
    })
}

/// Maps a `MAP_READ` buffer whose copy has been submitted, waits for it, hands its bytes to
/// `read`, and unmaps it.
pub(crate) fn read_mapped<T>(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T, RenderError> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| RenderError::Readback(e.to_string()))?;
    rx.recv().map_err(|e| RenderError::Readback(e.to_string()))?.map_err(|e| RenderError::Readback(e.to_string()))?;
    let data = slice.get_mapped_range().map_err(|e| RenderError::Readback(e.to_string()))?;
    let out = read(&data);
    drop(data);
    buffer.unmap();
    Ok(out)
}

/// Writes the tone-mapped frame as PNG.
pub fn write_png(frame: &CapturedFrame, path: &Path) -> Result<(), String> {
    let bytes: Vec<u8> = frame.ldr.iter().flat_map(|p| [p[0], p[1], p[2]]).collect();
    let image = image::RgbImage::from_raw(frame.width, frame.height, bytes).ok_or("frame size mismatch")?;
    write_atomically(path, |tmp| image.save_with_format(tmp, image::ImageFormat::Png).map_err(|e| e.to_string()))
}

/// Writes linear radiance as a 32-bit float RGB EXR.
pub fn write_exr(frame: &CapturedFrame, path: &Path) -> Result<(), String> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    write_atomically(path, |tmp| {
        exr::prelude::write_rgb_file(tmp, w, h, |x, y| {
            let p = frame.hdr[y * w + x];
            (p[0], p[1], p[2])
        })
        .map_err(|e| e.to_string())
    })
}

fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<(), String>) -> Result<(), String> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = path.file_name().ok_or_else(|| format!("{} is not a file path", path.display()))?.to_string_lossy();
    let ext = path.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_default();
    let cannot = |e: &dyn std::fmt::Display| format!("cannot write {}: {e}", path.display());
    lightloom_nodes::project::remove_stale_temp_files(path);
    // The temporary file keeps the extension: the image writers pick the format from it.
    let tmp =
        tempfile::Builder::new().prefix(&format!(".{name}.")).suffix(&ext).tempfile_in(dir).map_err(|e| cannot(&e))?;
    write(tmp.path()).map_err(|e| cannot(&e))?;
    lightloom_nodes::project::keep_permissions(tmp.as_file(), path).map_err(|e| cannot(&e))?;
    tmp.persist(path).map(|_| ()).map_err(|e| cannot(&e.error))
}
