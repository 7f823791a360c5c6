//! The viewport's WGSL, composed with `naga_oil`: each file under `shaders/` is a module that
//! `#import`s what it uses from the others, and a pipeline's shader is one top-level file and
//! its shader defs. The mesh passes share one entry file (`mesh.wgsl`, one `VertexOut` and
//! `vs_main`), each composing its own lighting module in by a def. Errors name the file.

use std::collections::HashMap;

use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, NagaModuleDescriptor, ShaderDefValue, ShaderLanguage, ShaderType,
};
use wgpu::naga;

/// A WGSL file: its name under `shaders/` and its text.
pub(crate) type Source = (&'static str, &'static str);

/// `shaders/<file>` as a [`Source`].
macro_rules! source {
    ($file:literal) => {
        ($file, include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../shaders/", $file)))
    };
}
pub(crate) use source;

/// The importable modules, each after those it imports.
const MODULES: [Source; 10] = [
    source!("common.wgsl"),
    source!("normal_map.wgsl"),
    source!("sun.wgsl"),
    source!("fog.wgsl"),
    source!("mesh_vertex.wgsl"),
    source!("mesh_irradiance.wgsl"),
    source!("mesh_prt.wgsl"),
    source!("mesh_wavelet.wgsl"),
    source!("mesh_rsl.wgsl"),
    source!("mesh_area.wgsl"),
];

/// The mesh passes' one entry file.
const MESH: Source = source!("mesh.wgsl");

/// A pipeline's shader: its top-level file and the def that picks its part.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Shader {
    pub label: &'static str,
    pub source: Source,
    /// A def set to true (a mesh pass's lighting module), if any.
    pub def: Option<&'static str>,
}

impl Shader {
    /// A mesh pass: `mesh.wgsl` with the lighting module `def` names.
    pub(crate) const fn mesh(label: &'static str, def: &'static str) -> Self {
        Self { label, source: MESH, def: Some(def) }
    }

    /// A shader that is one top-level file.
    pub(crate) const fn file(label: &'static str, source: Source) -> Self {
        Self { label, source, def: None }
    }

    /// The shader as naga IR, its normal-map paths kept when `normal_maps` (the `NORMAL_MAPS`
    /// def of `normal_map.wgsl`).
    pub(crate) fn compose(&self, normal_maps: bool) -> Result<naga::Module, String> {
        let mut defs = HashMap::from([("NORMAL_MAPS".to_string(), ShaderDefValue::Bool(normal_maps))]);
        if let Some(def) = self.def {
            defs.insert(def.to_string(), ShaderDefValue::Bool(true));
        }
        let mut composer = composer()?;
        let (file, source) = self.source;
        let made = composer.make_naga_module(NagaModuleDescriptor {
            source,
            file_path: file,
            shader_type: ShaderType::Wgsl,
            shader_defs: defs,
            ..Default::default()
        });
        made.map_err(|e| format!("{} (shaders/{file}): {}", self.label, e.emit_to_string(&composer)))
    }

    /// The composed shader as a module on `device`.
    pub(crate) fn module(&self, device: &wgpu::Device, normal_maps: bool) -> wgpu::ShaderModule {
        // The shaders are part of the program: one that does not compose is a build defect,
        // caught by `every_shader_composes_and_validates`.
        let module = self.compose(normal_maps).unwrap_or_else(|e| panic!("{e}"));
        device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(self.label),
            source: wgpu::ShaderSource::Naga(std::borrow::Cow::Owned(module)),
        })
    }
}

/// The composer holding [`MODULES`], made once (each is preprocessed when added; the defs
/// apply when a shader is made).
fn composer() -> Result<std::sync::MutexGuard<'static, Composer>, String> {
    static COMPOSER: std::sync::OnceLock<Result<std::sync::Mutex<Composer>, String>> = std::sync::OnceLock::new();
    let composer = COMPOSER.get_or_init(|| {
        // The device validates each module against what it supports.
        let mut composer = Composer::default().with_capabilities(naga::valid::Capabilities::all());
        for (file, source) in MODULES {
            let added = composer.add_composable_module(ComposableModuleDescriptor {
                source,
                file_path: file,
                language: ShaderLanguage::Wgsl,
                ..Default::default()
            });
            if let Err(e) = added {
                return Err(format!("shaders/{file}: {}", e.emit_to_string(&composer)));
            }
        }
        Ok(std::sync::Mutex::new(composer))
    });
    let composer = composer.as_ref().map_err(Clone::clone)?;
    // A panic while composing leaves the modules as they were added.
    Ok(composer.lock().unwrap_or_else(std::sync::PoisonError::into_inner))
}

/// A test kernel: `source` (which may `#import` the modules) composed alone.
#[cfg(test)]
pub(crate) fn compose_source(source: &'static str) -> Result<naga::Module, String> {
    Shader::file("test kernel", ("test.wgsl", source)).compose(true)
}
