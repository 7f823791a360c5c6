//! Graph edits on the project model: add, connect (with type and cycle checks), disconnect,
//! remove, duplicate, copy and paste. Pure functions of the project, used by the graph
//! editor, the inspector and the menus; each returns a reason when it refuses.

use lightloom_nodes::engine::spec::{NodeKindSpec, PortType};
use lightloom_nodes::kinds;
use lightloom_nodes::project::{Project, ProjectLink, ProjectNode};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};

/// `(node id, port name)`.
pub type PortRef = (String, String);

pub fn node<'p>(project: &'p Project, id: &str) -> Option<&'p ProjectNode> {
    project.nodes.iter().find(|n| n.id == id)
}

pub fn kind_of(project: &Project, id: &str) -> Option<&'static NodeKindSpec> {
    node(project, id).and_then(|n| kinds::kind(&n.kind))
}

/// A fresh id for a node of `kind`: its snake-case name, numbered when taken.
pub fn unique_id(project: &Project, kind: &str) -> String {
    let mut base = String::new();
    for (i, c) in kind.chars().enumerate() {
        if c.is_uppercase() && i > 0 {
            base.push('_');
        }
        base.push(c.to_ascii_lowercase());
    }
    if node(project, &base).is_none() {
        return base;
    }
    (2..).map(|n| format!("{base}{n}")).find(|id| node(project, id).is_none()).expect("an unused id")
}

/// Adds a node of `kind` at `position` (graph coordinates); returns its id.
pub fn add_node(project: &mut Project, kind: &str, position: [f32; 2]) -> Result<String, String> {
    let spec = kinds::kind(kind).ok_or_else(|| format!("unknown node kind `{kind}`"))?;
    let id = unique_id(project, spec.name);
    project.nodes.push(ProjectNode {
        id: id.clone(),
        kind: spec.name.into(),
        label: String::new(),
        position,
        params: BTreeMap::new(),
    });
    Ok(id)
}

fn port_type(project: &Project, (id, port): &PortRef, output: bool) -> Result<(PortType, bool), String> {
    let spec = kind_of(project, id).ok_or_else(|| format!("no node `{id}`"))?;
    let found = if output { spec.output(port) } else { spec.input(port) };
    let found =
        found.ok_or_else(|| format!("{} has no {} `{port}`", spec.label, if output { "output" } else { "input" }))?;
    Ok((found.ty, found.many))
}

/// Does `from` depend (transitively) on `to`'s node?
fn reaches(project: &Project, from: &str, to: &str) -> bool {
    let mut stack = vec![from.to_string()];
    let mut seen = std::collections::HashSet::new();
    while let Some(n) = stack.pop() {
        if n == to {
            return true;
        }
        if seen.insert(n.clone()) {
            stack.extend(project.links.iter().filter(|l| l.to.0 == n).map(|l| l.from.0.clone()));
        }
    }
    false
}

/// Why `from → to` cannot be linked, or `Ok` with whether it replaces an existing link.
pub fn check_link(project: &Project, from: &PortRef, to: &PortRef) -> Result<(), String> {
    let (out_ty, _) = port_type(project, from, true)?;
    let (in_ty, _) = port_type(project, to, false)?;
    if out_ty != in_ty {
        return Err(format!(
            "cannot link {}.{} to {}.{}: it carries {out_ty}, the input takes {in_ty}",
            from.0, from.1, to.0, to.1
        ));
    }
    if from.0 == to.0 || reaches(project, &from.0, &to.0) {
        return Err(format!("cannot link {}.{} to {}.{}: it would make a cycle", from.0, from.1, to.0, to.1));
    }
    Ok(())
}

/// Links `from → to` after [`check_link`]; a single input's previous link is replaced.
pub fn connect(project: &mut Project, from: &PortRef, to: &PortRef) -> Result<(), String> {
    check_link(project, from, to)?;
    let (_, many) = port_type(project, to, false)?;
    if project.links.iter().any(|l| &l.from == from && &l.to == to) {
        return Ok(());
    }
    if !many {
        project.links.retain(|l| &l.to != to);
    }
    project.links.push(ProjectLink { from: from.clone(), to: to.clone() });
    Ok(())
}

pub fn disconnect(project: &mut Project, from: &PortRef, to: &PortRef) {
    project.links.retain(|l| !(&l.from == from && &l.to == to));
}

/// Removes every link into (`input`) or out of (`!input`) a port.
pub fn disconnect_port(project: &mut Project, port: &PortRef, input: bool) {
    project.links.retain(|l| if input { &l.to != port } else { &l.from != port });
}

/// Removes nodes and their links.
pub fn remove_nodes(project: &mut Project, ids: &[String]) {
    project.nodes.retain(|n| !ids.contains(&n.id));
    project.links.retain(|l| !ids.contains(&l.from.0) && !ids.contains(&l.to.0));
}

/// Nodes and the links among them, as copied (serialised as RON on the system clipboard).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Clipboard {
    pub nodes: Vec<ProjectNode>,
    pub links: Vec<ProjectLink>,
}

impl Clipboard {
    pub fn copy(project: &Project, ids: &[String]) -> Self {
        Self {
            nodes: project.nodes.iter().filter(|n| ids.contains(&n.id)).cloned().collect(),
            links: project.links.iter().filter(|l| ids.contains(&l.from.0) && ids.contains(&l.to.0)).cloned().collect(),
        }
    }

    pub fn to_text(&self) -> String {
        ron::ser::to_string(self).unwrap_or_default()
    }

    pub fn from_text(text: &str) -> Option<Self> {
        ron::from_str(text).ok().filter(|c: &Clipboard| !c.nodes.is_empty())
    }
}

/// Pastes copied nodes with fresh ids, shifted by `offset`, keeping their internal links.
/// Returns the new ids.
pub fn paste(project: &mut Project, clipboard: &Clipboard, offset: [f32; 2]) -> Result<Vec<String>, String> {
    let mut renamed = HashMap::new();
    let mut added = Vec::new();
    for n in &clipboard.nodes {
        let spec = kinds::kind(&n.kind).ok_or_else(|| format!("unknown node kind `{}`", n.kind))?;
        let id = unique_id(project, spec.name);
        renamed.insert(n.id.clone(), id.clone());
        let mut copy = n.clone();
        copy.id = id.clone();
        copy.position = [n.position[0] + offset[0], n.position[1] + offset[1]];
        project.nodes.push(copy);
        added.push(id);
    }
    for l in &clipboard.links {
        if let (Some(a), Some(b)) = (renamed.get(&l.from.0), renamed.get(&l.to.0)) {
            project.links.push(ProjectLink { from: (a.clone(), l.from.1.clone()), to: (b.clone(), l.to.1.clone()) });
        }
    }
    Ok(added)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightloom_nodes::project::default_project;

    fn port(n: &str, p: &str) -> PortRef {
        (n.into(), p.into())
    }

    #[test]
    fn links_are_type_checked_and_cycles_refused() {
        let mut p = default_project();
        let err = connect(&mut p, &port("sky", "environment"), &port("output", "scene")).unwrap_err();
        assert!(err.contains("Environment") && err.contains("Scene"), "{err}");
        let err = connect(&mut p, &port("sky", "nope"), &port("output", "scene")).unwrap_err();
        assert!(err.contains("no output `nope`"), "{err}");
        // A single input's link is replaced; the material input takes several.
        let sky2 = add_node(&mut p, "EnvironmentMap", [0.0, 0.0]).unwrap();
        assert_eq!(sky2, "environment_map");
        connect(&mut p, &port(&sky2, "environment"), &port("output", "environment")).unwrap();
        let into_env: Vec<_> = p.links.iter().filter(|l| l.to == port("output", "environment")).collect();
        assert_eq!(into_env.len(), 1);
        assert_eq!(into_env[0].from.0, sky2);
        let m2 = add_node(&mut p, "BrdfEditor", [0.0, 0.0]).unwrap();
        connect(&mut p, &port(&m2, "material"), &port("output", "material")).unwrap();
        assert_eq!(p.links.iter().filter(|l| l.to == port("output", "material")).count(), 2);
        // The result is a valid graph.
        p.graph(std::path::Path::new("x.ron")).unwrap();
    }

    #[test]
    fn a_link_that_closes_a_loop_is_refused() {
        let mut p = default_project();
        let err = check_link(&p, &port("output", "x"), &port("sky", "y")).unwrap_err();
        assert!(err.contains("no output"), "{err}");
        // Point lights chain through their `lights` input: a → b, then b → a closes a loop.
        let a = add_node(&mut p, "PointLight", [0.0, 0.0]).unwrap();
        let b = add_node(&mut p, "PointLight", [0.0, 0.0]).unwrap();
        connect(&mut p, &port(&a, "lights"), &port(&b, "lights")).unwrap();
        let err = connect(&mut p, &port(&b, "lights"), &port(&a, "lights")).unwrap_err();
        assert!(err.contains("cycle"), "{err}");
        let err = check_link(&p, &port(&a, "lights"), &port(&a, "lights")).unwrap_err();
        assert!(err.contains("cycle"), "{err}");
        assert_eq!(p.links.iter().filter(|l| l.from.0 == b).count(), 0, "the refused link was not added");
    }

    #[test]
    fn copy_paste_remaps_ids_and_keeps_internal_links() {
        let mut p = default_project();
        let copied = Clipboard::copy(&p, &["sky".into(), "output".into()]);
        assert_eq!(copied.links.len(), 1, "only the link between copied nodes");
        let round = Clipboard::from_text(&copied.to_text()).unwrap();
        assert_eq!(round, copied);
        let added = paste(&mut p, &round, [40.0, 40.0]).unwrap();
        assert_eq!(added, vec!["environment_map".to_string(), "output2".to_string()]);
        assert_eq!(p.nodes.len(), 6);
        assert!(p.links.iter().any(|l| l.from.0 == "environment_map" && l.to.0 == "output2"));
        remove_nodes(&mut p, &added);
        assert_eq!(p, default_project());
    }
}
