//! The wgpu device: a real GPU where there is one, Mesa's lavapipe (Vulkan on the CPU)
//! where there is not.

/// Why rendering could not start or finish.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(
        "no GPU adapter found ({0}); on a machine without a GPU install Mesa's CPU Vulkan driver \
         (`apt-get install mesa-vulkan-drivers`) or set WGPU_BACKEND=gl"
    )]
    NoAdapter(String),
    #[error("the GPU device could not be created: {0}")]
    Device(String),
    #[error("reading the rendered image back failed: {0}")]
    Readback(String),
    #[error("{0}")]
    Invalid(String),
}

/// Instance, adapter, device and queue.
pub struct GpuContext {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
}

impl GpuContext {
    /// A device for offscreen rendering. `WGPU_BACKEND` (vulkan, gl, …) selects the backend.
    pub fn headless() -> Result<Self, RenderError> {
        // Vulkan first (a GPU, or lavapipe on the CPU), then GL; probing GL needlessly prints
        // EGL noise on headless machines.
        let attempts: Vec<wgpu::Backends> = match std::env::var("WGPU_BACKEND") {
            Ok(_) => vec![wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all())],
            Err(_) => vec![wgpu::Backends::VULKAN, wgpu::Backends::GL],
        };
        let mut last_error = String::from("no backend tried");
        for backends in attempts {
            let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
            descriptor.backends = backends;
            let instance = wgpu::Instance::new(descriptor);
            match pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: false,
                compatible_surface: None,
                ..Default::default()
            })) {
                Ok(adapter) => return Self::from_adapter(instance, adapter),
                Err(e) => last_error = format!("{backends:?}: {e}"),
            }
        }
        Err(RenderError::NoAdapter(last_error))
    }

    /// A device on a given adapter (the editor picks one compatible with its window).
    pub fn from_adapter(instance: wgpu::Instance, adapter: wgpu::Adapter) -> Result<Self, RenderError> {
        let (device, queue) = pollster::block_on(adapter.request_device(&device_descriptor(&adapter)))
            .map_err(|e| RenderError::Device(e.to_string()))?;
        Ok(Self { instance, adapter, device, queue })
    }

    /// Wraps a device someone else created (the editor's window device, made with
    /// [`device_descriptor`] so the renderer gets the limits it needs).
    pub fn from_parts(
        instance: wgpu::Instance,
        adapter: wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
    ) -> Self {
        Self { instance, adapter, device, queue }
    }

    /// Blocks until the GPU has finished all submitted work (for timing).
    pub fn wait(&self) -> Result<(), RenderError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| RenderError::Device(e.to_string()))
    }

    /// "name (backend, device type)".
    pub fn describe(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type)
    }
}

/// What the renderer asks of a device: per-vertex coefficient buffers (PRT, triple products)
/// can be large, so it takes the storage-buffer sizes the adapter offers.
pub fn device_descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
    let supported = adapter.limits();
    let required_limits = wgpu::Limits {
        max_storage_buffer_binding_size: supported.max_storage_buffer_binding_size,
        max_buffer_size: supported.max_buffer_size,
        // The wavelet relight kernel reads five buffers and writes three, and the wavelet mesh
        // pass's vertex stage reads eight (WebGPU's default is 8).
        max_storage_buffers_per_shader_stage: supported.max_storage_buffers_per_shader_stage.min(8),
        // Scene passes bind five groups: camera, medium, their own, sun, normal maps.
        max_bind_groups: supported.max_bind_groups.min(8),
        ..wgpu::Limits::downlevel_defaults().using_resolution(supported)
    };
    wgpu::DeviceDescriptor { label: Some("lightloom"), required_limits, ..Default::default() }
}
