//! The validated, evaluable form of a project's node graph.

use crate::engine::spec::{NodeKindSpec, ParamValue};
use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::path::PathBuf;

/// A node with its kind resolved and every parameter present (defaults filled in).
#[derive(Clone, Debug)]
pub struct GraphNode {
    pub id: String,
    pub kind: &'static NodeKindSpec,
    pub params: BTreeMap<String, ParamValue>,
}

impl GraphNode {
    /// The files parameter `name` names (relative to the project): a file parameter's, or
    /// the models of an object list.
    pub fn files(&self, name: &str) -> Vec<&str> {
        self.params.get(name).map_or_else(Vec::new, ParamValue::files)
    }
}

/// A link from an output port to an input port.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Link {
    pub from_node: String,
    pub from_port: String,
    pub to_node: String,
    pub to_port: String,
}

/// A problem found while building a graph, naming the node, port or parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct GraphError {
    pub node: Option<String>,
    pub port: Option<String>,
    pub param: Option<String>,
    pub message: String,
}

impl GraphError {
    fn node(node: &str, message: impl Into<String>) -> Self {
        Self { node: Some(node.into()), port: None, param: None, message: message.into() }
    }

    fn port(node: &str, port: &str, message: impl Into<String>) -> Self {
        Self { node: Some(node.into()), port: Some(port.into()), param: None, message: message.into() }
    }

    fn param(node: &str, param: &str, message: impl Into<String>) -> Self {
        Self { node: Some(node.into()), port: None, param: Some(param.into()), message: message.into() }
    }
}

impl std::error::Error for GraphError {}

impl fmt::Display for GraphError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(node) = &self.node {
            write!(f, "node `{node}`")?;
            if let Some(port) = &self.port {
                write!(f, " port `{port}`")?;
            }
            if let Some(param) = &self.param {
                write!(f, " parameter `{param}`")?;
            }
            write!(f, ": ")?;
        }
        write!(f, "{}", self.message)
    }
}

/// A node as given by a project (kind by name, possibly partial parameters).
pub struct NodeInput<'a> {
    pub id: &'a str,
    pub kind: &'a str,
    pub params: &'a BTreeMap<String, ParamValue>,
}

/// A validated graph: acyclic, well-typed, every parameter in range, and every required input
/// connected on the nodes that feed a sink (a kind with no outputs: what is drawn or baked).
/// A node that feeds no sink never blocks the rest: its unconnected inputs are `warnings`.
#[derive(Clone, Debug)]
pub struct Graph {
    pub nodes: Vec<GraphNode>,
    pub links: Vec<Link>,
    /// Relative asset paths resolve against this directory.
    pub project_dir: PathBuf,
    order: Vec<usize>,
    /// `(node, input port)` → index of the node feeding it.
    /// Upstream nodes of each connected input, in project order.
    feeds: HashMap<(String, String), Vec<usize>>,
    /// Problems that block nothing (nodes that feed no sink, with an unconnected input).
    pub warnings: Vec<GraphError>,
    /// Per node (same order as `nodes`): whether it is a sink or feeds one.
    feeds_sink: Vec<bool>,
}

impl Graph {
    /// Validates and builds a graph; returns every problem found, not just the first.
    pub fn build(
        nodes: &[NodeInput],
        links: &[Link],
        project_dir: PathBuf,
        registry: &'static [NodeKindSpec],
    ) -> Result<Self, Vec<GraphError>> {
        let mut errors = Vec::new();
        let mut built: Vec<GraphNode> = Vec::new();
        let mut ids: HashMap<&str, usize> = HashMap::new();
        for input in nodes {
            if input.id.is_empty() || input.id.contains(['.', ' ']) {
                errors.push(GraphError::node(input.id, "node ids must be non-empty and contain no dots or spaces"));
            }
            if ids.contains_key(input.id) {
                errors.push(GraphError::node(input.id, "duplicate node id: each node needs its own id"));
                continue;
            }
            ids.insert(input.id, built.len());
            let Some(kind) = registry.iter().find(|k| k.name == input.kind) else {
                let known: Vec<&str> = registry.iter().map(|k| k.name).collect();
                errors.push(GraphError::node(
                    input.id,
                    format!("unknown node kind `{}` (known kinds: {})", input.kind, known.join(", ")),
                ));
                ids.remove(input.id);
                continue;
            };
            let mut params = BTreeMap::new();
            for (name, value) in input.params {
                match kind.param(name) {
                    None => {
                        let known: Vec<&str> = kind.params.iter().map(|p| p.name).collect();
                        errors.push(GraphError::param(
                            input.id,
                            name,
                            format!("{} has no such parameter (known: {})", kind.name, known.join(", ")),
                        ));
                    }
                    Some(spec) => match spec.check(value) {
                        Ok(()) => {
                            params.insert(name.clone(), value.clone());
                        }
                        Err(why) => errors.push(GraphError::param(input.id, name, why)),
                    },
                }
            }
            for spec in &kind.params {
                params.entry(spec.name.to_string()).or_insert_with(|| spec.default_value());
            }
            built.push(GraphNode { id: input.id.to_string(), kind, params });
        }
        let mut connected: HashMap<(&str, &str), &Link> = HashMap::new();
        let mut valid_links: Vec<Link> = Vec::new();
        for link in links {
            let from = ids.get(link.from_node.as_str()).map(|&i| &built[i]);
            let to = ids.get(link.to_node.as_str()).map(|&i| &built[i]);
            let (Some(from), Some(to)) = (from, to) else {
                for (node, port) in [(&link.from_node, &link.from_port), (&link.to_node, &link.to_port)] {
                    if !ids.contains_key(node.as_str()) {
                        errors.push(GraphError::port(node, port, "link refers to a node that does not exist"));
                    }
                }
                continue;
            };
            let out = from.kind.output(&link.from_port);
            let inp = to.kind.input(&link.to_port);
            match (out, inp) {
                (None, _) => errors.push(GraphError::port(
                    &from.id,
                    &link.from_port,
                    format!("{} has no output `{}`", from.kind.name, link.from_port),
                )),
                (_, None) => errors.push(GraphError::port(
                    &to.id,
                    &link.to_port,
                    format!("{} has no input `{}`", to.kind.name, link.to_port),
                )),
                (Some(o), Some(i)) if o.ty != i.ty => errors.push(GraphError::port(
                    &to.id,
                    &link.to_port,
                    format!("expects {}, but `{}.{}` provides {}", i.ty, from.id, link.from_port, o.ty),
                )),
                (_, Some(i)) => {
                    let key = (link.to_node.as_str(), link.to_port.as_str());
                    if connected.contains_key(&key) && !i.many {
                        errors.push(GraphError::port(&to.id, &link.to_port, "input has more than one link"));
                    } else {
                        connected.entry(key).or_insert(link);
                    }
                    valid_links.push(link.clone());
                }
            }
        }
        // Nodes that are sinks or feed one, by walking links upstream from the sinks.
        let mut feeds_sink: std::collections::HashSet<&str> =
            built.iter().filter(|n| n.kind.outputs.is_empty()).map(|n| n.id.as_str()).collect();
        loop {
            let before = feeds_sink.len();
            for link in &valid_links {
                if feeds_sink.contains(link.to_node.as_str()) {
                    feeds_sink.insert(link.from_node.as_str());
                }
            }
            if feeds_sink.len() == before {
                break;
            }
        }
        let sink_feeders: Vec<bool> = built.iter().map(|n| feeds_sink.contains(n.id.as_str())).collect();
        let mut warnings = Vec::new();
        for node in &built {
            for port in &node.kind.inputs {
                if port.required && !connected.contains_key(&(node.id.as_str(), port.name)) {
                    let message = format!("required {} input is not connected", port.ty);
                    if feeds_sink.contains(node.id.as_str()) {
                        errors.push(GraphError::port(&node.id, port.name, message));
                    } else {
                        let message = format!("{message} (the node feeds no output, so nothing waits for it)");
                        warnings.push(GraphError::port(&node.id, port.name, message));
                    }
                }
            }
        }
        let order = match topological_order(&built, &valid_links) {
            Ok(order) => order,
            Err(cycle) => {
                errors.push(GraphError::node(&cycle[0], format!("links form a cycle: {}", cycle.join(" -> "))));
                Vec::new()
            }
        };
        if !errors.is_empty() {
            return Err(errors);
        }
        let mut links = valid_links;
        // Stable: links into one port keep their project order.
        links.sort_by(|a, b| (&a.to_node, &a.to_port).cmp(&(&b.to_node, &b.to_port)));
        let mut feeds: HashMap<(String, String), Vec<usize>> = HashMap::default();
        for l in &links {
            feeds.entry((l.to_node.clone(), l.to_port.clone())).or_default().push(ids[l.from_node.as_str()]);
        }
        Ok(Self { nodes: built, links, project_dir, order, feeds, warnings, feeds_sink: sink_feeders })
    }

    /// Whether `id` is a sink (a kind with no outputs) or feeds one: what evaluation can need.
    pub fn feeds_sink(&self, id: &str) -> bool {
        self.nodes.iter().position(|n| n.id == id).is_some_and(|i| self.feeds_sink[i])
    }

    pub fn node(&self, id: &str) -> Option<&GraphNode> {
        self.nodes.iter().find(|n| n.id == id)
    }

    /// Nodes, upstream before downstream.
    pub fn topological_order(&self) -> impl Iterator<Item = &GraphNode> {
        self.order.iter().map(|&i| &self.nodes[i])
    }

    /// The (first) node feeding `port` of `node`, if connected.
    pub fn upstream(&self, node: &str, port: &str) -> Option<&GraphNode> {
        self.feeds.get(&(node.to_string(), port.to_string())).and_then(|v| v.first()).map(|&i| &self.nodes[i])
    }

    /// Every node feeding `port` of `node`, in project order.
    pub fn upstream_all(&self, node: &str, port: &str) -> Vec<&GraphNode> {
        self.feeds
            .get(&(node.to_string(), port.to_string()))
            .map_or(Vec::new(), |v| v.iter().map(|&i| &self.nodes[i]).collect())
    }

    /// Sets a parameter after checking it against the kind's spec.
    pub fn set_param(&mut self, node: &str, param: &str, value: ParamValue) -> Result<(), GraphError> {
        let n = self.nodes.iter_mut().find(|n| n.id == node).ok_or_else(|| GraphError::node(node, "no such node"))?;
        let spec = n.kind.param(param).ok_or_else(|| {
            let known: Vec<&str> = n.kind.params.iter().map(|p| p.name).collect();
            GraphError::param(
                node,
                param,
                format!("{} has no such parameter (known: {})", n.kind.name, known.join(", ")),
            )
        })?;
        spec.check(&value).map_err(|why| GraphError::param(node, param, why))?;
        n.params.insert(param.to_string(), value);
        Ok(())
    }
}

/// Kahn's algorithm; on a cycle returns the node ids along one cycle.
fn topological_order(nodes: &[GraphNode], links: &[Link]) -> Result<Vec<usize>, Vec<String>> {
    let index: HashMap<&str, usize> = nodes.iter().enumerate().map(|(i, n)| (n.id.as_str(), i)).collect();
    let mut indegree = vec![0usize; nodes.len()];
    let mut out: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    for l in links {
        let (a, b) = (index[l.from_node.as_str()], index[l.to_node.as_str()]);
        out[a].push(b);
        indegree[b] += 1;
    }
    let mut ready: Vec<usize> = (0..nodes.len()).rev().filter(|&i| indegree[i] == 0).collect();
    let mut order = Vec::with_capacity(nodes.len());
    while let Some(i) = ready.pop() {
        order.push(i);
        for &j in out[i].iter().rev() {
            indegree[j] -= 1;
            if indegree[j] == 0 {
                ready.push(j);
            }
        }
    }
    if order.len() == nodes.len() {
        return Ok(order);
    }
    // Walk backwards along remaining edges to find a cycle to name.
    let remaining: Vec<usize> = (0..nodes.len()).filter(|i| indegree[*i] > 0).collect();
    let mut path = vec![remaining[0]];
    loop {
        let last = *path.last().unwrap();
        let next = (0..nodes.len()).find(|&j| indegree[j] > 0 && out[j].contains(&last)).unwrap();
        if let Some(pos) = path.iter().position(|&p| p == next) {
            let mut cycle: Vec<String> = path[pos..].iter().rev().map(|&i| nodes[i].id.clone()).collect();
            cycle.push(cycle[0].clone());
            return Err(cycle);
        }
        path.push(next);
    }
}
