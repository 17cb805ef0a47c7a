//! Import circles between the modules of a crate: module `a` naming `crate::b…` (or
//! `super::b…`) while `b` names `a`, directly or through others. A circle means neither module
//! can be read, tested or moved without the other; the workspace is kept free of them, and the
//! test below checks every crate.
//!
//! A module is a file under `src/` (`a/mod.rs` is `a`, `a/b.rs` is `a/b`). What it imports is
//! every `crate::` and `super::` path in its code, comment lines and its `#[cfg(test)]` part
//! left out, with `{…}` groups expanded; a path names the deepest module file it reaches. A
//! submodule naming its own parent (or an ancestor) is not counted: a parent declares its
//! children, so that edge is always there and is not a circle a reader has to untangle.
use anyhow::{Context, Result};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The modules of the crate whose sources are in `src`, each with the modules it imports.
pub fn graph(src: &Path) -> Result<BTreeMap<String, BTreeSet<String>>> {
    let mut files = BTreeMap::new();
    collect(src, src, &mut files)?;
    let names: BTreeSet<String> = files.keys().cloned().collect();
    let mut graph = BTreeMap::new();
    for (name, text) in &files {
        let parent = name.rsplit_once('/').map_or("", |(p, _)| p);
        let mut imports = BTreeSet::new();
        for (base, path) in paths(&code(text)) {
            let mut current = if base == "crate" {
                String::new()
            } else {
                parent.to_string()
            };
            let mut reached = None;
            for segment in path {
                let next = if current.is_empty() {
                    segment
                } else {
                    format!("{current}/{segment}")
                };
                if !names.contains(&next) {
                    break;
                }
                reached = Some(next.clone());
                current = next;
            }
            if let Some(m) = reached
                && m != *name
                && !name.starts_with(&format!("{m}/"))
            {
                imports.insert(m);
            }
        }
        graph.insert(name.clone(), imports);
    }
    Ok(graph)
}

/// The circles of `graph`: its strongly connected components of more than one module, each
/// sorted (Tarjan's algorithm).
pub fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct State<'a> {
        graph: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        found: Vec<Vec<String>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let i = s.index.len();
        s.index.insert(v, i);
        s.low.insert(v, i);
        s.stack.push(v);
        for w in &s.graph[v] {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if s.stack.contains(&w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                component.push(w.to_string());
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                s.found.push(component);
            }
        }
    }
    let mut s = State {
        graph,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v.as_str()) {
            visit(&mut s, v);
        }
    }
    s.found.sort();
    s.found
}

fn collect(src: &Path, dir: &Path, out: &mut BTreeMap<String, String>) -> Result<()> {
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let path = entry?.path();
        if path.is_dir() {
            collect(src, &path, out)?;
        } else if path.extension().is_some_and(|e| e == "rs") {
            let rel = path.strip_prefix(src).expect("under src").with_extension("");
            let rel = rel.to_string_lossy().replace('\\', "/");
            let name = rel.strip_suffix("/mod").unwrap_or(&rel).to_string();
            let text = std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))?;
            out.insert(name, text);
        }
    }
    Ok(())
}

/// A file's code: comment lines dropped, and everything from its `#[cfg(test)]` on.
fn code(text: &str) -> String {
    let before_tests = text.split("#[cfg(test)]").next().unwrap_or_default();
    before_tests
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Every `crate::…` and `super::…` path in `code`, braces expanded: (`crate` or `super`, its
/// segments).
fn paths(code: &str) -> Vec<(&'static str, Vec<String>)> {
    let mut out = Vec::new();
    for base in ["crate", "super"] {
        let pattern = format!("{base}::");
        let mut rest = code;
        while let Some(at) = rest.find(&pattern) {
            let preceded_by_ident = rest[..at]
                .chars()
                .next_back()
                .is_some_and(|c| c.is_alphanumeric() || c == '_');
            rest = &rest[at + pattern.len()..];
            if preceded_by_ident {
                continue;
            }
            let mut chars = rest.chars().peekable();
            for path in use_tree(&mut chars) {
                out.push((base, path));
            }
        }
    }
    out
}

/// Parses `segment(::segment)*(::{tree, …})?` and returns every path it spells.
fn use_tree(chars: &mut std::iter::Peekable<std::str::Chars>) -> Vec<Vec<String>> {
    let skip_space = |chars: &mut std::iter::Peekable<std::str::Chars>| {
        while chars.peek().is_some_and(|c| c.is_whitespace()) {
            chars.next();
        }
    };
    skip_space(chars);
    if chars.peek() == Some(&'{') {
        chars.next();
        let mut all = Vec::new();
        loop {
            skip_space(chars);
            match chars.peek() {
                Some('}') => {
                    chars.next();
                    break;
                }
                Some(',') => {
                    chars.next();
                }
                None => break,
                _ => {
                    let before = all.len();
                    all.extend(use_tree(chars));
                    if all.len() == before {
                        // Not a path (`*`, `self as x`…): skip to the next item.
                        while chars.peek().is_some_and(|c| *c != ',' && *c != '}') {
                            chars.next();
                        }
                    }
                }
            }
        }
        return all;
    }
    let mut segment = String::new();
    while let Some(&c) = chars.peek() {
        if c.is_alphanumeric() || c == '_' {
            segment.push(c);
            chars.next();
        } else {
            break;
        }
    }
    if segment.is_empty() {
        return Vec::new();
    }
    // A `::` continues the path; anything else ends it.
    let mut lookahead = chars.clone();
    if lookahead.next() == Some(':') && lookahead.next() == Some(':') {
        chars.next();
        chars.next();
        let tails = use_tree(chars);
        if tails.is_empty() {
            return vec![vec![segment]];
        }
        return tails
            .into_iter()
            .map(|t| std::iter::once(segment.clone()).chain(t).collect())
            .collect();
    }
    vec![vec![segment]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, files: &[(&str, &str)]) {
        for (name, text) in files {
            let path = dir.join(name);
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, text).unwrap();
        }
    }

    #[test]
    fn no_crate_in_the_workspace_has_an_import_circle() {
        let root = crate::root();
        let mut crates: Vec<_> = std::fs::read_dir(root.join("crates"))
            .unwrap()
            .map(|e| e.unwrap().path().join("src"))
            .filter(|p| p.is_dir())
            .collect();
        crates.push(root.join("xtask/src"));
        crates.sort();
        assert!(crates.len() >= 6, "the crates were not found: {crates:?}");
        for src in crates {
            let graph = graph(&src).unwrap();
            assert!(graph.len() > 1, "{}: no modules read", src.display());
            let found = circles(&graph);
            assert!(found.is_empty(), "{}: import circles {found:?}", src.display());
        }
    }

    /// The checker finds circles through `use` groups, nested modules, `super::` and paths in
    /// code, and ignores comments, tests and a child naming its parent.
    #[test]
    fn circles_are_found_and_only_circles() {
        let dir = tempfile::tempdir().unwrap();
        write(
            dir.path(),
            &[
                ("lib.rs", "mod a; mod b; mod c; mod load;"),
                // a -> b through a nested group, b -> a through a plain path in code.
                ("a.rs", "use crate::{x::y, b::{self, Thing}};"),
                ("b.rs", "fn f() { crate::a::g(); }"),
                // c names a only in a comment and in its tests.
                ("c.rs", "// crate::a\n#[cfg(test)]\nmod t { use crate::a; }"),
                // load/m <-> load/n through super::, and load/m naming its parent.
                ("load/mod.rs", "mod m; mod n; pub use m::M;"),
                ("load/m.rs", "use super::{n::N, *}; use crate::load::helper;"),
                ("load/n.rs", "use super::m;"),
            ],
        );
        let graph = graph(dir.path()).unwrap();
        assert_eq!(graph["c"], BTreeSet::new());
        assert_eq!(graph["load/m"], BTreeSet::from(["load/n".to_string()]));
        assert_eq!(
            circles(&graph),
            vec![
                vec!["a".to_string(), "b".to_string()],
                vec!["load/m".to_string(), "load/n".to_string()]
            ]
        );
        // Without b's call there is one circle left.
        write(dir.path(), &[("b.rs", "fn f() {}")]);
        assert_eq!(circles(&super::graph(dir.path()).unwrap()).len(), 1);
    }
}
