//! Requests: what an evaluation must produce, and which stages that pulls in.

use super::{Graph, Instance, StageIndex};

/// A stage of a node, named by node id and stage name.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StageRef {
    pub node: String,
    pub stage: String,
}

impl StageRef {
    pub fn new(node: impl Into<String>, stage: impl Into<String>) -> Self {
        Self { node: node.into(), stage: stage.into() }
    }
}

impl std::fmt::Display for StageRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}", self.node, self.stage)
    }
}

/// One tier of a [`Request`]: stages wanted together, with what they are for.
#[derive(Clone, Debug, PartialEq)]
pub struct Tier {
    /// What the tier is for ("preview: unshadowed", "output `output`: mode sh_prt"), shown in
    /// reports.
    pub label: String,
    pub stages: Vec<StageRef>,
}

/// What an evaluation must produce. Only the requested stages and what they read run; the
/// rest are reported as not needed. Tiers run in order: every stage a tier needs finishes
/// before the next tier starts, so a cheap first tier (an unshadowed preview) is ready while
/// expensive work (shadowed transport) is still computing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Request {
    pub tiers: Vec<Tier>,
}

impl Request {
    /// Every stage of every node (tests, benchmarks, `lightloom eval --all`).
    pub fn everything(graph: &Graph) -> Self {
        let stages = graph
            .nodes
            .iter()
            .flat_map(|n| n.kind.stages.iter().map(|s| StageRef::new(n.id.clone(), s.name)))
            .collect();
        Self { tiers: vec![Tier { label: "every stage".into(), stages }] }
    }

    /// The stages that read a file named by a parameter (so loading every asset means
    /// evaluating these; `lightloom info` does).
    pub fn assets(graph: &Graph) -> Self {
        let mut stages = Vec::new();
        for node in &graph.nodes {
            let reads_file = |s: &&crate::engine::spec::StageSpec| s.params.iter().any(|p| !node.files(p).is_empty());
            for stage in node.kind.stages.iter().filter(reads_file) {
                stages.push(StageRef::new(&node.id, stage.name));
            }
        }
        Self::new("assets", stages)
    }

    pub fn new(label: impl Into<String>, stages: Vec<StageRef>) -> Self {
        Self { tiers: vec![Tier { label: label.into(), stages }] }
    }

    /// Adds a tier that runs after the ones before it.
    pub fn then(mut self, label: impl Into<String>, stages: Vec<StageRef>) -> Self {
        self.tiers.push(Tier { label: label.into(), stages });
        self
    }

    /// Adds stages to the first tier (creating it if needed).
    pub fn with_first(mut self, label: &str, stages: Vec<StageRef>) -> Self {
        if stages.is_empty() {
            return self;
        }
        match self.tiers.first_mut() {
            Some(first) => {
                first.label = format!("{}; {label}", first.label);
                first.stages.extend(stages);
            }
            None => self.tiers.push(Tier { label: label.into(), stages }),
        }
        self
    }

    /// What every tier is for, in order.
    pub fn describe(&self) -> String {
        self.tiers.iter().map(|t| t.label.as_str()).collect::<Vec<_>>().join("; ")
    }
}

/// For each instance, the first request tier that needs it (directly or through what it
/// reads), or `None` when nothing requested reads it. Unknown stages become notes.
pub(super) fn needed_tiers(
    graph: &Graph,
    instances: &[Instance],
    index: &StageIndex,
    request: &Request,
    notes: &mut Vec<String>,
) -> Vec<Option<usize>> {
    let mut tier_of: Vec<Option<usize>> = vec![None; instances.len()];
    for (tier, spec) in request.tiers.iter().enumerate() {
        let mut stack: Vec<usize> = Vec::new();
        for target in &spec.stages {
            match index.get(&(target.node.as_str(), target.stage.as_str())) {
                Some(&i) => stack.push(i),
                None if graph.node(&target.node).is_none() => {
                    notes.push(format!("requested stage {target}: there is no node `{}`", target.node))
                }
                None => notes.push(format!("requested stage {target}: the node has no such stage")),
            }
        }
        while let Some(i) = stack.pop() {
            if tier_of[i].is_some() {
                continue;
            }
            tier_of[i] = Some(tier);
            stack.extend(instances[i].deps.iter().map(|(d, _)| *d));
        }
    }
    tier_of
}
