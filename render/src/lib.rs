//! Lightloom's renderer: a wgpu device (windowed or headless), the viewport renderer that
//! draws a [`FrameInputs`](lightloom_nodes::frame::FrameInputs), and offscreen capture
//! to PNG/EXR. It knows nothing of the editor; WGSL lives in `shaders/`.

pub mod capture;
pub mod device;
mod passes;
mod shaders;
pub mod shexp;
pub mod viewport;

pub use capture::{CapturedFrame, write_exr, write_png};
pub use device::{GpuContext, RenderError, device_descriptor};
pub use passes::prt::MAX_PRT_BANDS;
pub use passes::sun::SHADOW_MAP_BYTES as SUN_SHADOW_MAP_BYTES;
pub use passes::wavelet::RelightOn;
pub use viewport::{CameraView, ViewportRenderer};
