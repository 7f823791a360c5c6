//! Point lights and the participating medium (Sun 2008 ch. 3, `fog.wgsl`): group 1 of every
//! scene pass. They are shaded in the same fragment as each surface because they depend on its
//! normal and material (eqs. 3.27–3.29), so this pass binds data and draws nothing itself.

use super::{entry, pod_uniform_buffer, stage_value, upload_table_layers, upload_tables, vec4};
use crate::{GpuContext, RenderError};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{MAX_LIGHTS, MAX_MATERIALS, MediumFrame};
use lightloom_nodes::light::{PROFILE_PHI, PROFILE_THETA};
use lightloom_nodes::single_scattering::{
    FTable, MAX_ENVIRONMENT_FOG_BANDS, PHONG_STEPS_PER_OCTAVE, PhongGTables, Table2,
};

/// `fog.wgsl` `Fog`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct FogParams {
    /// rgb: β per channel (1/m); w: 1 when a medium is linked.
    pub(crate) beta: [f32; 4],
    /// Phase polynomial weights `W_0..W_2`; w: how many.
    pub(crate) phase: [f32; 4],
    /// x: point light count; y: `G_n` ladder layers; z: layers per octave of exponent; w: 1
    /// when the shader adds the scattered environment's irradiance to surfaces.
    pub(crate) counts: [f32; 4],
    /// rgb: the environment's attenuation `e^{-βD}`; w: bands of `environment_scattered`.
    pub(crate) environment: [f32; 4],
    /// SH coefficients of the light fog scatters from the environment (eq. 3.35).
    pub(crate) environment_scattered: [[f32; 4]; MAX_ENVIRONMENT_FOG_BANDS * MAX_ENVIRONMENT_FOG_BANDS],
    /// Per material: Phong-equivalent lobe weight (rgb) and exponent (w; 0 = no lobe).
    pub(crate) specular: [[f32; 4]; MAX_MATERIALS],
    pub(crate) light_position: [[f32; 4]; MAX_LIGHTS],
    pub(crate) light_intensity: [[f32; 4]; MAX_LIGHTS],
    /// Per light: its profile's axis (xyz) and whether it has one (w: 1; 0 is isotropic).
    pub(crate) light_axis: [[f32; 4]; MAX_LIGHTS],
    /// Per light: its profile's `φ = 0` direction.
    pub(crate) light_x: [[f32; 4]; MAX_LIGHTS],
}

pub(crate) struct MediumPass {
    pub layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    pub bind_group: wgpu::BindGroup,
    /// The `F^k` and `G_n` stages the bound tables came from.
    tables: Option<Key>,
    /// The bound tables and light profiles (one layer per light, [`PROFILE_PHI`] ×
    /// [`PROFILE_THETA`]), and a hash of the profiles' values.
    views: [wgpu::TextureView; 3],
    profiles: u64,
}

impl MediumPass {
    pub fn new(gpu: &GpuContext) -> Self {
        let layout = gpu.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("medium"),
            entries: &[
                entry::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                entry::texture(1, wgpu::TextureViewDimension::D2Array, false),
                entry::texture(2, wgpu::TextureViewDimension::D2Array, false),
                entry::texture(3, wgpu::TextureViewDimension::D2Array, false),
            ],
        });
        let params = pod_uniform_buffer::<FogParams>(&gpu.device, "fog");
        let views = [
            upload_tables(gpu, "f-tables", 1, &[0.0]),
            upload_tables(gpu, "g-tables", 1, &[0.0]),
            upload_table_layers(gpu, "light profiles", (1, 1), &[1.0]),
        ];
        let bind_group = Self::bind(gpu, &layout, &params, &views);
        Self { layout, params, bind_group, tables: None, views, profiles: 0 }
    }

    fn bind(
        gpu: &GpuContext,
        layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        views: &[wgpu::TextureView; 3],
    ) -> wgpu::BindGroup {
        gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("medium"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&views[0]) },
                wgpu::BindGroupEntry { binding: 2, resource: wgpu::BindingResource::TextureView(&views[1]) },
                wgpu::BindGroupEntry { binding: 3, resource: wgpu::BindingResource::TextureView(&views[2]) },
            ],
        })
    }

    /// The lights' profiles as one layer each (isotropic lights' layers stay unread), uploaded
    /// when their values change.
    fn upload_profiles(&mut self, gpu: &GpuContext, medium: &MediumFrame) -> bool {
        let lights = &medium.lights[..medium.lights.len().min(MAX_LIGHTS)];
        if lights.iter().all(|l| l.profile.is_none()) {
            return false;
        }
        let mut hasher = std::hash::DefaultHasher::new();
        for light in lights {
            let bytes: &[u8] = light.profile.as_ref().map_or(&[], |p| bytemuck::cast_slice(&p.values));
            std::hash::Hash::hash(bytes, &mut hasher);
        }
        let hash = std::hash::Hasher::finish(&hasher);
        if hash == self.profiles {
            return false;
        }
        let layer = PROFILE_PHI * PROFILE_THETA;
        let mut values = vec![1.0f32; layer * lights.len()];
        for (light, out) in lights.iter().zip(values.chunks_mut(layer)) {
            if let Some(p) = &light.profile {
                out.copy_from_slice(&p.values);
            }
        }
        self.views[2] = upload_table_layers(gpu, "light profiles", (PROFILE_PHI as u32, PROFILE_THETA as u32), &values);
        // Bound at once: a later failure in this frame must not leave the old layers bound
        // under the new hash.
        self.bind_group = Self::bind(gpu, &self.layout, &self.params, &self.views);
        self.profiles = hash;
        true
    }

    /// Uniforms every frame, tables when their stages change.
    pub fn prepare(&mut self, gpu: &GpuContext, medium: &MediumFrame) -> Result<(), RenderError> {
        let mut params: FogParams = bytemuck::Zeroable::zeroed();
        params.environment = [1.0, 1.0, 1.0, 0.0];
        params.counts[0] = medium.lights.len().min(MAX_LIGHTS) as f32;
        for (i, l) in medium.lights.iter().take(MAX_LIGHTS).enumerate() {
            params.light_position[i] = vec4(l.position, 1.0);
            params.light_intensity[i] = vec4(l.intensity, 0.0);
            if let Some(p) = &l.profile {
                params.light_axis[i] = vec4(p.frame.z_axis.to_array(), 1.0);
                params.light_x[i] = vec4(p.frame.x_axis.to_array(), 0.0);
            }
        }
        self.upload_profiles(gpu, medium);
        let mut rebind = false;
        for (slot, lobe) in params.specular.iter_mut().zip(&medium.surface_lobes) {
            if let Some((weight, exponent)) = lobe {
                *slot = vec4(*weight, *exponent as f32);
            }
        }
        if let Some(fog) = &medium.fog {
            if let Some(environment) = &fog.environment {
                let bands = environment.fog.scattered.len() as f32;
                params.environment = vec4(environment.fog.attenuation, bands);
                for (dst, src) in params.environment_scattered.iter_mut().zip(&environment.scattered.coeffs) {
                    *dst = vec4(*src, 0.0);
                }
                params.counts[3] = f32::from(u8::from(fog.scatter_onto_surfaces));
            }
            params.beta = vec4(fog.beta, 1.0);
            for (k, w) in fog.phase.iter().take(3).enumerate() {
                params.phase[k] = *w as f32;
            }
            params.phase[3] = fog.phase.len().min(3) as f32;
            let f = stage_value::<Vec<FTable>>(&fog.f_tables)?;
            let g = stage_value::<PhongGTables>(&fog.g_tables)?;
            params.counts[1] = g.tables.len() as f32;
            params.counts[2] = PHONG_STEPS_PER_OCTAVE as f32;
            let key = fog.f_tables.key ^ fog.g_tables.key.rotate_left(7);
            if self.tables != Some(key) {
                let layers = |tables: &mut dyn Iterator<Item = &Table2>| {
                    tables.flat_map(|t| t.values.iter().copied()).collect::<Vec<f32>>()
                };
                let f_size = f.first().map_or(1, |t| t.table.width) as u32;
                let g_size = g.tables.first().map_or(1, |t| t.table.width) as u32;
                let f_values = layers(&mut f.iter().map(|t| &t.table));
                let g_values = layers(&mut g.tables.iter().map(|t| &t.table));
                self.views[0] = upload_tables(gpu, "f-tables", f_size, &f_values);
                self.views[1] = upload_tables(gpu, "g-tables", g_size, &g_values);
                self.tables = Some(key);
                rebind = true;
            }
        }
        if rebind {
            self.bind_group = Self::bind(gpu, &self.layout, &self.params, &self.views);
        }
        gpu.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        Ok(())
    }
}
