//! Every node kind: parameters, ports and stages. The math lives in the technique modules
//! (`sh`, `wavelet`, …); a kind's stages only wire parameters to it.

pub mod area_light;
pub mod blockers;
pub mod brdf;
pub mod brdf_normal_map;
pub mod environment;
pub mod fog;
pub mod lights;
pub mod output;
pub use output::adaptive::AdaptiveError;
pub mod rsl;
pub mod scene;
pub mod spot_light;

use crate::engine::spec::NodeKindSpec;
use std::sync::OnceLock;

/// All node kinds, in menu order.
pub fn registry() -> &'static [NodeKindSpec] {
    static REGISTRY: OnceLock<Vec<NodeKindSpec>> = OnceLock::new();
    REGISTRY.get_or_init(|| {
        let mut kinds = vec![
            environment::spec(),
            scene::spec(),
            brdf::spec(),
            output::spec(),
            fog::spec(),
            lights::point_light_spec(),
            spot_light::spec(),
            area_light::spec(),
            rsl::spec(),
            blockers::spec(),
        ];
        // Techniques' work on the scenes and materials they draw.
        for extension in rsl::receivers::extensions() {
            extension.apply(&mut kinds);
        }
        kinds
    })
}

/// Looks a kind up by name.
pub fn kind(name: &str) -> Option<&'static NodeKindSpec> {
    registry().iter().find(|k| k.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_producer_provides_what_its_readers_read() {
        crate::engine::spec::check_port_contracts(registry()).unwrap();
        // The contract is derived from the readers: the Output reads the scene's transport.
        assert!(crate::engine::spec::PortType::Scene.read_stages(registry()).contains("transport_sh"));
        // And it catches a producer without a stage its readers read.
        let mut kinds = registry().to_vec();
        let scene = kinds.iter_mut().find(|k| k.name == "Scene").unwrap();
        scene.stages.retain(|s| s.name != "receivers");
        let err = crate::engine::spec::check_port_contracts(&kinds).unwrap_err();
        assert!(err.contains("Scene") && err.contains("receivers"), "{err}");
    }

    #[test]
    fn registry_is_self_consistent() {
        for kind in registry() {
            let mut seen = std::collections::HashSet::new();
            for stage in &kind.stages {
                assert!(seen.insert(stage.name), "{}: duplicate stage {}", kind.name, stage.name);
                for p in stage.params {
                    assert!(
                        kind.param(p).is_some() || *p == crate::engine::spec::NODE_ID,
                        "{}.{} reads unknown parameter {p}",
                        kind.name,
                        stage.name
                    );
                }
                for s in stage.stages {
                    // Own stages must be declared earlier (the stage order is a topological order).
                    assert!(seen.contains(s) && s != &stage.name, "{}.{} reads later stage {s}", kind.name, stage.name);
                }
                for (port, _) in stage.inputs {
                    assert!(kind.input(port).is_some(), "{}.{}: no input {port}", kind.name, stage.name);
                }
            }
            let mut names = std::collections::HashSet::new();
            for p in &kind.params {
                assert!(names.insert(p.name), "{}: duplicate parameter {}", kind.name, p.name);
                assert!(p.check(&p.default_value()).is_ok(), "{}.{} default is invalid", kind.name, p.name);
                if let crate::engine::spec::ParamKind::Choice { options, labels, .. } = &p.kind {
                    assert!(
                        labels.is_empty() || labels.len() == options.len(),
                        "{}.{}: {} labels for {} options",
                        kind.name,
                        p.name,
                        labels.len(),
                        options.len()
                    );
                }
                assert!(
                    kind.stages.iter().any(|s| s.params.contains(&p.name)),
                    "{}.{} is read by no stage",
                    kind.name,
                    p.name
                );
            }
        }
    }
}
