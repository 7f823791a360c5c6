//! The crate's layers, read from its source: plain data and techniques at the bottom, the engine
//! beside them, the node kinds above the techniques, frame assembly above the kinds, and the
//! bake above the frame. A module never imports one above it, so no import circle forms and a
//! technique can be read, tested and reused without the node layer.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers above the techniques, lowest first. Every other top-level module is a technique
/// or plain data.
const LAYERS: &[&str] = &["engine", "kinds", "frame", "project", "bake", "fuzzing"];

/// What the engine (the graph model, keys, caches, scheduling) may name: itself and the plain
/// data its parameters carry. A new technique or kind never edits it.
const ENGINE_MAY_IMPORT: &[&str] = &["engine", "scene_object", "paint", "picture", "choice_enum", "stage_type"];

/// Longest non-test source file, in lines.
const MAX_FILE_LINES: usize = 800;

/// Longest function, in lines, but for declarative tables (a node kind's `spec`).
const MAX_FUNCTION_LINES: usize = 150;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Whether a file holds tests only (`tests.rs`, anything under a `tests/` or `ui_tests/`
/// folder, benches and integration tests).
fn is_test_file(relative: &Path) -> bool {
    relative.file_name().is_some_and(|n| n == "tests.rs")
        || relative.components().any(|c| matches!(c.as_os_str().to_str(), Some("tests" | "ui_tests" | "benches")))
}

/// The file's code before its inline `#[cfg(test)] mod tests`, with comment lines blanked (so
/// line numbers stay right).
fn code_of(source: &str) -> Vec<&str> {
    let mut lines: Vec<&str> = Vec::new();
    let mut it = source.lines().peekable();
    while let Some(line) = it.next() {
        let inline_tests = |next: &&str| next.trim_start().starts_with("mod ") && next.trim_end().ends_with('{');
        if line.trim() == "#[cfg(test)]" && it.peek().is_some_and(inline_tests) {
            break;
        }
        lines.push(if line.trim_start().starts_with("//") { "" } else { line });
    }
    lines
}

/// The top-level module a `src/`-relative path belongs to (`frame/gather.rs` → `frame`).
fn unit_of(relative: &Path) -> String {
    let first = relative.components().next().unwrap().as_os_str().to_string_lossy().into_owned();
    first.strip_suffix(".rs").map(str::to_owned).unwrap_or(first)
}

/// Every `crate::NAME` a line names, with each name of a grouped `crate::{a, b::c}`.
fn crate_names(line: &str) -> impl Iterator<Item = String> + '_ {
    let word = |text: &str| -> String { text.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect() };
    line.match_indices("crate::").flat_map(move |(at, _)| {
        let rest = &line[at + 7..];
        match rest.strip_prefix('{') {
            Some(group) => {
                let group = &group[..group.find('}').unwrap_or(group.len())];
                group.split(',').map(|item| word(item.trim())).filter(|w| !w.is_empty()).collect::<Vec<_>>()
            }
            None => vec![word(rest)],
        }
    })
}

/// `unit → imported unit → where`, over the `nodes` crate's non-test code.
fn imports() -> BTreeMap<String, BTreeMap<String, Vec<String>>> {
    imports_of("nodes")
}

/// `unit → imported unit → where`, over a workspace crate's non-test code (its top-level
/// modules; the crate root aside).
fn imports_of(krate: &str) -> BTreeMap<String, BTreeMap<String, Vec<String>>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().join(krate).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut graph: BTreeMap<String, BTreeMap<String, Vec<String>>> = BTreeMap::new();
    for path in files {
        let relative = path.strip_prefix(&src).unwrap().to_path_buf();
        if is_test_file(&relative) || relative == Path::new("lib.rs") || relative == Path::new("main.rs") {
            continue;
        }
        let unit = unit_of(&relative);
        let source = std::fs::read_to_string(&path).unwrap();
        let edges = graph.entry(unit.clone()).or_default();
        for (n, line) in code_of(&source).into_iter().enumerate() {
            for name in crate_names(line).filter(|name| *name != unit) {
                edges.entry(name).or_default().push(format!("{}:{}", relative.display(), n + 1));
            }
        }
    }
    graph
}

/// A circle through `from`, if any (depth-first, each unit once).
fn circle(graph: &BTreeMap<String, BTreeMap<String, Vec<String>>>, from: &str) -> Option<Vec<String>> {
    fn walk(
        graph: &BTreeMap<String, BTreeMap<String, Vec<String>>>,
        at: &str,
        target: &str,
        path: &mut Vec<String>,
        seen: &mut BTreeSet<String>,
    ) -> bool {
        for next in graph.get(at).into_iter().flat_map(|e| e.keys()) {
            if next == target {
                return true;
            }
            if seen.insert(next.clone()) {
                path.push(next.clone());
                if walk(graph, next, target, path, seen) {
                    return true;
                }
                path.pop();
            }
        }
        false
    }
    let mut path = vec![from.to_owned()];
    walk(graph, from, from, &mut path, &mut BTreeSet::new()).then_some(path)
}

#[test]
fn no_crate_has_an_import_circle() {
    for krate in ["nodes", "render", "app"] {
        let graph = imports_of(krate);
        assert!(graph.len() > 3, "{krate}'s modules were found");
        for unit in graph.keys() {
            if let Some(path) = circle(&graph, unit) {
                let hops: Vec<String> = path
                    .iter()
                    .zip(path.iter().cycle().skip(1))
                    .map(|(a, b)| format!("{a} → {b} ({})", graph[a][b][0]))
                    .collect();
                panic!("an import circle in {krate}: {}", hops.join(", "));
            }
        }
    }
}

#[test]
fn techniques_import_no_layer_above_them() {
    let graph = imports();
    assert!(graph.contains_key("brdf") && graph.contains_key("frame"), "the crate's modules were found");
    for (unit, edges) in graph.iter().filter(|(unit, _)| !LAYERS.contains(&unit.as_str())) {
        let above = ["kinds", "frame", "project", "bake"];
        if let Some((name, at)) = edges.iter().find(|(name, _)| above.contains(&name.as_str())) {
            panic!("the technique `{unit}` imports `crate::{name}` ({}): techniques sit below the node layer", at[0]);
        }
    }
    // Each layer imports only those below it.
    for (i, layer) in LAYERS.iter().enumerate() {
        for above in &LAYERS[i + 1..] {
            if let Some(at) = graph.get(*layer).and_then(|e| e.get(*above)) {
                panic!("`{layer}` imports `crate::{above}` ({}), a layer above it", at[0]);
            }
        }
    }
}

#[test]
fn the_engine_imports_no_technique() {
    let graph = imports();
    for (name, at) in &graph["engine"] {
        assert!(ENGINE_MAY_IMPORT.contains(&name.as_str()), "the engine imports `crate::{name}` ({})", at[0]);
    }
}

/// The non-test sources of the `nodes`, `render` and `app` crates: `(crate/src/path, text)`.
fn workspace_sources() -> Vec<(String, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let mut out = Vec::new();
    for krate in ["nodes", "render", "app"] {
        let src = root.join(krate).join("src");
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        for path in files {
            let relative = path.strip_prefix(&src).unwrap();
            if !is_test_file(relative) {
                let text = std::fs::read_to_string(&path).unwrap();
                out.push((format!("{krate}/src/{}", relative.display()), text));
            }
        }
    }
    assert!(out.len() > 100, "the workspace's sources were found");
    out
}

/// Files split by concern stay readable: none of the workspace's non-test sources is longer
/// than [`MAX_FILE_LINES`], inline tests included (long tests move to a `tests.rs` beside).
#[test]
fn no_source_file_is_over_800_lines() {
    let mut long = Vec::new();
    for (name, source) in workspace_sources() {
        let lines = source.lines().count();
        if lines > MAX_FILE_LINES {
            long.push(format!("{name} ({lines} lines)"));
        }
    }
    assert!(long.is_empty(), "over {MAX_FILE_LINES} lines, tests aside: {}", long.join(", "));
}

/// Functions over [`MAX_FUNCTION_LINES`] in `lines` (non-test code): `(name, first line, length)`.
/// A function ends at the first line that is its indentation and a closing brace.
fn long_functions(lines: &[&str]) -> Vec<(String, usize, usize)> {
    let mut out = Vec::new();
    for (i, line) in lines.iter().enumerate() {
        let trimmed = line.trim_start();
        let indent = &line[..line.len() - trimmed.len()];
        let after_fn = ["fn ", "pub fn ", "pub(crate) fn ", "pub(super) fn ", "const fn ", "pub const fn "]
            .iter()
            .find_map(|p| trimmed.strip_prefix(p));
        let Some(rest) = after_fn else { continue };
        let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        let close = format!("{indent}}}");
        let Some(end) = lines[i + 1..].iter().position(|l| *l == close) else { continue };
        let length = end + 2;
        let declarative = name == "spec" || lines[i..=i + end].iter().take(8).any(|l| l.contains("-> NodeKindSpec"));
        if length > MAX_FUNCTION_LINES && !declarative {
            out.push((name, i + 1, length));
        }
    }
    out
}

/// Functions split by concern stay readable: none is longer than [`MAX_FUNCTION_LINES`] but
/// the declarative tables that describe node kinds.
#[test]
fn no_function_is_over_150_lines() {
    let mut long = Vec::new();
    for (name, source) in workspace_sources() {
        for (function, line, length) in long_functions(&code_of(&source)) {
            long.push(format!("{name}:{line} `{function}` ({length} lines)"));
        }
    }
    assert!(long.is_empty(), "functions over {MAX_FUNCTION_LINES} lines: {}", long.join(", "));
}

/// The checks see what they should: a circle and a file's inline tests.
#[test]
fn the_checks_find_a_circle_and_skip_inline_tests() {
    let mut graph: BTreeMap<String, BTreeMap<String, Vec<String>>> = BTreeMap::new();
    graph.entry("a".into()).or_default().insert("b".into(), vec!["a.rs:1".into()]);
    graph.entry("b".into()).or_default().insert("c".into(), vec!["b.rs:1".into()]);
    assert_eq!(circle(&graph, "a"), None);
    graph.entry("c".into()).or_default().insert("a".into(), vec!["c.rs:1".into()]);
    assert_eq!(circle(&graph, "a"), Some(vec!["a".to_owned(), "b".to_owned(), "c".to_owned()]));
    let code = code_of(
        "#[cfg(test)]\nmod tests;\nuse crate::x;\nuse crate::{kinds, frame::Keyed};\n// crate::y\n#[cfg(test)]\nmod tests {\n    use crate::z;\n}\n",
    );
    let names: Vec<String> = code.iter().flat_map(|l| crate_names(l)).collect();
    assert_eq!(names, ["x", "kinds", "frame"]);
    let body = vec!["    let x = 1;"; MAX_FUNCTION_LINES];
    let long: Vec<&str> = ["pub fn long() {"].into_iter().chain(body.iter().copied()).chain(["}"]).collect();
    assert_eq!(long_functions(&long), [("long".to_owned(), 1, MAX_FUNCTION_LINES + 2)]);
    let table: Vec<&str> =
        ["pub fn spec() -> NodeKindSpec {"].into_iter().chain(body.iter().copied()).chain(["}"]).collect();
    assert!(long_functions(&table).is_empty(), "a kind's declaration is a table");
}
