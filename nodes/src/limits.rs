//! Resource limits on what Lightloom reads and computes, each enforced with an error that
//! names the file or node and the limit (see the README's "Limits" table).

use std::io::Read;
use std::path::Path;

/// Largest project, glTF, glTF buffer or environment-map file read, in bytes.
pub const MAX_FILE_BYTES: u64 = 2 << 30;
/// Most pixels an environment map may declare (16384 × 8192).
pub const MAX_IMAGE_PIXELS: u64 = 16384 * 8192;
/// Largest radiance kept from an image; larger finite values are clamped with a warning
/// (a sun is about 1e5; 1e9 leaves room while keeping SH and sums finite in f32).
pub const MAX_RADIANCE: f32 = 1e9;
/// A `.gltf` file's JSON, read to find the files it refers to.
pub const MAX_GLTF_JSON_BYTES: u64 = 256 << 20;

/// Most mesh instances a glTF node hierarchy may expand to.
pub const MAX_GLTF_INSTANCES: usize = 100_000;
/// Most nodes a glTF node hierarchy may expand to (a node listed twice as a child is visited
/// twice: 2 KB of JSON can describe 2^40 visits).
pub const MAX_GLTF_NODE_VISITS: usize = 1_000_000;
/// Most triangles a scene may hold in total.
pub const MAX_TRIANGLES: usize = 20_000_000;
/// Most visibility rays one transport precompute may cast (receivers × rays per receiver):
/// about an hour on a 2-core machine. Higher settings are refused with the estimate.
pub const MAX_TOTAL_RAYS: u64 = 4_000_000_000;
/// Largest world coordinate, in metres: beyond it f32 geometry loses all precision.
pub const MAX_COORDINATE: f32 = 1e7;
/// Largest per-vertex table of the square-light mode (self-visibility tables at 1 KiB per
/// vertex, per-vertex visibility at 4 bytes per vertex and light), in bytes.
pub const MAX_RSL_TABLE_BYTES: u64 = 1 << 30;

/// Largest area-light transport (receivers × (top-face cells × 4 B per distinct face + 64 B per
/// light for its part beyond the face)), checked before any ray is traced.
pub const MAX_AREA_TRANSPORT_BYTES: u64 = 1 << 30;
/// The high-order SH mode's per-vertex incident radiance (vertices × (level+1)² × 12 B).
pub const MAX_INCIDENT_BYTES: u64 = 1 << 30;
/// Largest render target, in bytes of GPU memory (colour, depth, MSAA and readback).
pub const MAX_RENDER_TARGET_BYTES: u64 = 3 << 30;

/// Checks that `path` is a regular file of at most `limit` bytes (before a decoder opens it:
/// a FIFO would hang it, `/dev/zero` would never end); returns its size.
pub fn check_regular_file(path: &Path, limit: u64) -> Result<u64, String> {
    let name = path.display();
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read {name}: {e}"))?;
    if !meta.is_file() {
        return Err(format!("{name} is not a regular file"));
    }
    if meta.len() > limit {
        return Err(format!("{name} is {} MiB; the limit is {} MiB", meta.len() >> 20, limit >> 20));
    }
    Ok(meta.len())
}

/// Reads a regular file of at most `limit` bytes: special files (FIFOs, devices such as
/// `/dev/zero`) and larger files are refused before anything is read.
pub fn read_regular_file(path: &Path, limit: u64) -> Result<Vec<u8>, String> {
    let name = path.display();
    let size = check_regular_file(path, limit)?;
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read {name}: {e}"))?;
    let mut bytes = Vec::with_capacity(size as usize);
    // `take`: a file that grows while being read stops at the limit.
    file.take(limit + 1).read_to_end(&mut bytes).map_err(|e| format!("cannot read {name}: {e}"))?;
    if bytes.len() as u64 > limit {
        return Err(format!("{name} grew past {} MiB while being read", limit >> 20));
    }
    Ok(bytes)
}
