//! Point lights and the participating medium (Sun 2008 ch. 3, `fog.wgsl`): group 1 of every
//! scene pass. They are shaded in the same fragment as each surface because they depend on its
//! normal and material (eqs. 3.27–3.29), so this pass binds data and draws nothing itself.

use super::{entry, stage_value, uniform_buffer, upload_table_layers, upload_tables, write_uniform};
use crate::{GpuContext, RenderError};
use glam::{DVec3, Vec3};
use lightloom_nodes::engine::Key;
use lightloom_nodes::frame::{MAX_LIGHTS, MAX_MATERIALS, MediumFrame};
use lightloom_nodes::light::{PROFILE_PHI, PROFILE_THETA};
use lightloom_nodes::single_scattering::{
    FTable, MAX_ENVIRONMENT_FOG_BANDS, PHONG_STEPS_PER_OCTAVE, PhongGTables, Table2,
};

/// `fog.wgsl` `FogLight`.
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct FogLight {
    pub(crate) position: Vec3,
    /// 1 when it has an angular profile.
    pub(crate) profiled: u32,
    pub(crate) intensity: Vec3,
    /// The profile's axis and its `φ = 0` direction.
    pub(crate) axis: Vec3,
    pub(crate) x_axis: Vec3,
}

/// `fog.wgsl` `SurfaceLobe`: a material's Phong-equivalent lobe (exponent 0: none).
#[derive(Clone, Copy, Default, encase::ShaderType)]
pub(crate) struct SurfaceLobe {
    pub(crate) weight: Vec3,
    pub(crate) exponent: f32,
}

/// `fog.wgsl` `Fog`.
#[derive(encase::ShaderType)]
pub(crate) struct FogParams {
    /// β per channel (1/m).
    pub(crate) beta: Vec3,
    /// 1 when a medium is linked.
    pub(crate) linked: u32,
    /// Phase polynomial weights `W_0..W_2`, and how many there are.
    pub(crate) phase: Vec3,
    pub(crate) phase_terms: u32,
    pub(crate) light_count: u32,
    /// The `G_n` ladder's layers, and its layers per octave of exponent.
    pub(crate) g_layers: u32,
    pub(crate) g_layers_per_octave: f32,
    /// 1 when the shader adds the scattered environment's irradiance to surfaces.
    pub(crate) scatter_onto_surfaces: u32,
    /// The environment's attenuation `e^{-βD}`, and the bands of `environment_scattered`.
    pub(crate) attenuation: Vec3,
    pub(crate) scattered_bands: u32,
    /// SH coefficients of the light fog scatters from the environment (eq. 3.35).
    pub(crate) environment_scattered: [Vec3; MAX_ENVIRONMENT_FOG_BANDS * MAX_ENVIRONMENT_FOG_BANDS],
    /// Per material.
    pub(crate) lobes: [SurfaceLobe; MAX_MATERIALS],
    pub(crate) lights: [FogLight; MAX_LIGHTS],
}

impl Default for FogParams {
    fn default() -> Self {
        Self {
            beta: Vec3::ZERO,
            linked: 0,
            phase: Vec3::ZERO,
            phase_terms: 0,
            light_count: 0,
            g_layers: 0,
            g_layers_per_octave: 0.0,
            scatter_onto_surfaces: 0,
            attenuation: Vec3::ONE,
            scattered_bands: 0,
            environment_scattered: [Vec3::ZERO; MAX_ENVIRONMENT_FOG_BANDS * MAX_ENVIRONMENT_FOG_BANDS],
            lobes: [SurfaceLobe::default(); MAX_MATERIALS],
            lights: [FogLight::default(); MAX_LIGHTS],
        }
    }
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
        let params = uniform_buffer::<FogParams>(&gpu.device, "fog");
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
        let v3 = |v: [f64; 3]| DVec3::from(v).as_vec3();
        let mut params = FogParams { light_count: medium.lights.len().min(MAX_LIGHTS) as u32, ..FogParams::default() };
        for (slot, l) in params.lights.iter_mut().zip(&medium.lights) {
            *slot = FogLight { position: v3(l.position), intensity: v3(l.intensity), ..FogLight::default() };
            if let Some(p) = &l.profile {
                (slot.profiled, slot.axis, slot.x_axis) = (1, p.frame.z_axis.as_vec3(), p.frame.x_axis.as_vec3());
            }
        }
        self.upload_profiles(gpu, medium);
        let mut rebind = false;
        for (slot, lobe) in params.lobes.iter_mut().zip(&medium.surface_lobes) {
            if let Some((weight, exponent)) = lobe {
                *slot = SurfaceLobe { weight: v3(*weight), exponent: *exponent as f32 };
            }
        }
        if let Some(fog) = &medium.fog {
            if let Some(environment) = &fog.environment {
                params.attenuation = v3(environment.fog.attenuation);
                params.scattered_bands = environment.fog.scattered.len() as u32;
                for (dst, src) in params.environment_scattered.iter_mut().zip(&environment.scattered.coeffs) {
                    *dst = v3(*src);
                }
                params.scatter_onto_surfaces = u32::from(fog.scatter_onto_surfaces);
            }
            (params.beta, params.linked) = (v3(fog.beta), 1);
            params.phase = Vec3::from_array(std::array::from_fn(|k| fog.phase.get(k).map_or(0.0, |w| *w as f32)));
            params.phase_terms = fog.phase.len().min(3) as u32;
            let f = stage_value::<Vec<FTable>>(&fog.f_tables)?;
            let g = stage_value::<PhongGTables>(&fog.g_tables)?;
            params.g_layers = g.tables.len() as u32;
            params.g_layers_per_octave = PHONG_STEPS_PER_OCTAVE as f32;
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
        write_uniform(&gpu.queue, &self.params, &params);
        Ok(())
    }
}
