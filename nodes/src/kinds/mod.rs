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
        vec![
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
        ]
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
                for (port, upstream) in stage.inputs {
                    let input =
                        kind.input(port).unwrap_or_else(|| panic!("{}.{}: no input {port}", kind.name, stage.name));
                    assert!(
                        input.ty.provided_stages().contains(upstream),
                        "{}.{}: {port} offers no {upstream}",
                        kind.name,
                        stage.name
                    );
                }
            }
            for out in &kind.outputs {
                for provided in out.ty.provided_stages() {
                    assert!(kind.stage(provided).is_some(), "{} output {} lacks stage {provided}", kind.name, out.name);
                }
            }
            for p in &kind.params {
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
