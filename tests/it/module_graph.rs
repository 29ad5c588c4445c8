//! The import graph of `src/` keeps the design rule of
//! `docs/architecture.md` ("Imports point one way"): within a checked
//! folder the files import each other without a circle, and `render` and
//! `report` do not depend on each other both ways.
//!
//! A file's references are the paths it names outside comments and
//! strings: `use` trees and inline paths, starting at `crate::`,
//! `super::`, `self::` or at a child module of the file's own module.
//! Each resolves to the file of the longest module prefix it names. In a
//! folder's graph the nodes are its files and its subfolders (one node
//! each, all their files together); in a file-by-file graph (`shadow/`,
//! whose kit and interface use each other's items) every file below it is
//! a node and an item named through a `mod.rs` re-export counts as an
//! import of the file that defines it. The only references that do not
//! count are a `mod.rs`'s `pub use` of items inside its own folder (its
//! re-exports).
//! Method calls name no path: they are not seen.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;
use std::path::Path;

#[test]
fn raster_files_import_one_way() {
    assert_folder_acyclic("raster");
}

/// `shadow/` file by file: the interface (`technique.rs`) and the kit
/// use each other's items, but no two files do, in a circle.
#[test]
fn shadow_files_import_one_way() {
    assert_files_acyclic("shadow");
}

#[test]
fn compare_files_import_one_way() {
    assert_folder_acyclic("compare");
}

#[test]
fn render_and_report_depend_one_way() {
    assert_acyclic_among("", &["render/", "report/"]);
}

#[test]
fn the_raster_graph_is_seen() {
    // A parser that found nothing would pass every check.
    let graph = folder_graph(&crate_sources(), "raster");
    let tile = &graph.edges["tile/"];
    for needed in ["setup.rs", "fragment.rs", "framebuffer.rs", "state.rs"] {
        assert!(tile.contains_key(needed), "tile/ → {needed} not found");
    }
    assert!(graph.edges["pipeline.rs"].contains_key("tile/"));
}

/// Fails, printing the circle and where each step is imported, when the
/// files (and subfolders) of `src/<folder>` import each other in a circle.
fn assert_folder_acyclic(folder: &str) {
    let graph = folder_graph(&crate_sources(), folder);
    if let Some(cycle) = graph.find_cycle(None) {
        panic!("src/{folder}/: {}", graph.describe(&cycle));
    }
}

/// Like [`assert_folder_acyclic`], for the graph among `nodes` of `folder`
/// only (`""` is `src/` itself, whose nodes are `name.rs` and `name/`).
fn assert_acyclic_among(folder: &str, nodes: &[&str]) {
    let graph = folder_graph(&crate_sources(), folder);
    if let Some(cycle) = graph.find_cycle(Some(nodes)) {
        panic!("src/{folder}: {}", graph.describe(&cycle));
    }
}

/// Every `.rs` file under `src/` but the binary's `main.rs`: its path
/// relative to `src/` (with `/`) and its text.
fn crate_sources() -> Vec<(String, String)> {
    fn walk(dir: &Path, root: &Path, out: &mut Vec<(String, String)>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir)
            .expect("read src/")
            .map(|entry| entry.expect("read src/").path())
            .collect();
        entries.sort();
        for path in entries {
            if path.is_dir() {
                walk(&path, root, out);
            } else if path.extension().is_some_and(|ext| ext == "rs") {
                let relative = path.strip_prefix(root).expect("under src/");
                let relative = relative.to_string_lossy().replace('\\', "/");
                if relative != "main.rs" {
                    out.push((relative, std::fs::read_to_string(&path).expect("read")));
                }
            }
        }
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut out = Vec::new();
    walk(&root, &root, &mut out);
    out
}

/// The module path of a file: `lib.rs` → `[]`, `a/mod.rs` and `a.rs` →
/// `[a]`.
fn module_of(file: &str) -> Vec<String> {
    let mut parts: Vec<String> = file.split('/').map(str::to_string).collect();
    let last = parts.pop().unwrap_or_default();
    if last != "mod.rs" && last != "lib.rs" {
        parts.push(last.trim_end_matches(".rs").to_string());
    }
    parts
}

/// One path a file names.
struct Reference {
    /// The file it resolves to.
    target: String,
    /// The first segment after the module prefix (the item it names in
    /// `target`), if any.
    item: Option<String>,
    /// A `mod.rs`'s `pub use` of an item inside its own folder.
    reexport: bool,
    line: usize,
    text: String,
}

/// The references of every file.
fn references(sources: &[(String, String)]) -> BTreeMap<String, Vec<Reference>> {
    let modules: BTreeMap<Vec<String>, String> = sources
        .iter()
        .map(|(file, _)| (module_of(file), file.clone()))
        .collect();
    // The longest module prefix of `path` that is a file, and the segment
    // after it.
    let resolve = |path: &[String]| -> Option<(String, Option<String>)> {
        (0..=path.len()).rev().find_map(|len| {
            let file = modules.get(&path[..len])?;
            Some((file.clone(), path.get(len).cloned()))
        })
    };
    let mut out = BTreeMap::new();
    for (file, text) in sources {
        let module = module_of(file);
        let folder = file.rsplit_once('/').map_or("", |(dir, _)| dir);
        let is_mod_rs = file.ends_with("mod.rs");
        let mut found = Vec::new();
        for named in named_paths(text) {
            // Where the path starts: inline modules (`mod tests { .. }`)
            // are one `super` deeper than the file.
            let mut base = module.clone();
            base.extend(named.inline_modules.iter().cloned());
            let mut segments = named.segments.iter().peekable();
            match segments.peek().map(|s| s.as_str()) {
                Some("crate") => {
                    base.clear();
                    segments.next();
                }
                Some("self") => {
                    segments.next();
                }
                Some("super") => {
                    while segments.peek().is_some_and(|s| *s == "super") {
                        base.pop();
                        segments.next();
                    }
                }
                // A child module of the file's own module, named bare.
                Some(first) if named.inline_modules.is_empty() => {
                    let mut child = module.clone();
                    child.push(first.to_string());
                    if !modules.contains_key(&child) {
                        continue;
                    }
                }
                _ => continue,
            }
            base.extend(segments.cloned());
            let Some((target, item)) = resolve(&base) else {
                continue;
            };
            let inside_folder = target.starts_with(&format!("{folder}/"));
            found.push(Reference {
                reexport: is_mod_rs && named.public_use && inside_folder,
                target,
                item,
                line: named.line,
                text: named.segments.join("::"),
            });
        }
        out.insert(file.clone(), found);
    }
    out
}

/// A path as written: its segments, the inline modules it sits in, and
/// whether it is part of a `pub use`.
struct NamedPath {
    segments: Vec<String>,
    inline_modules: Vec<String>,
    public_use: bool,
    line: usize,
}

/// A token of Rust source, with its line.
#[derive(Clone, PartialEq, Debug)]
enum Token {
    Ident(String),
    /// `::`
    PathSep,
    Punct(char),
}

/// Identifiers and punctuation of `text`, without comments, strings,
/// characters and lifetimes.
fn tokens(text: &str) -> Vec<(Token, usize)> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let (mut at, mut line) = (0, 1);
    let count_lines =
        |from: usize, to: usize| chars[from..to].iter().filter(|&&c| c == '\n').count();
    while at < chars.len() {
        let c = chars[at];
        let next = chars.get(at + 1).copied().unwrap_or(' ');
        if c == '\n' {
            line += 1;
            at += 1;
        } else if c.is_whitespace() {
            at += 1;
        } else if c == '/' && next == '/' {
            while at < chars.len() && chars[at] != '\n' {
                at += 1;
            }
        } else if c == '/' && next == '*' {
            let (start, mut depth) = (at, 0);
            while at < chars.len() {
                if chars[at] == '/' && chars.get(at + 1) == Some(&'*') {
                    depth += 1;
                    at += 2;
                } else if chars[at] == '*' && chars.get(at + 1) == Some(&'/') {
                    depth -= 1;
                    at += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    at += 1;
                }
            }
            line += count_lines(start, at);
        } else if c == 'r' && (next == '#' || next == '"') && raw_string_end(&chars, at).is_some() {
            let end = raw_string_end(&chars, at).unwrap_or(chars.len());
            line += count_lines(at, end);
            at = end;
        } else if c == '"' || (c == 'b' && next == '"') {
            let start = at;
            at += if c == 'b' { 2 } else { 1 };
            while at < chars.len() && chars[at] != '"' {
                at += if chars[at] == '\\' { 2 } else { 1 };
            }
            at += 1;
            line += count_lines(start, at.min(chars.len()));
        } else if c == '\'' {
            // A character literal ('x', '\n', '\u{..}') or a lifetime.
            if next == '\\' {
                at += 2;
                while at < chars.len() && chars[at] != '\'' {
                    at += 1;
                }
                at += 1;
            } else if chars.get(at + 2) == Some(&'\'') {
                at += 3;
            } else {
                at += 1;
                while at < chars.len() && (chars[at].is_alphanumeric() || chars[at] == '_') {
                    at += 1;
                }
            }
        } else if c.is_alphabetic() || c == '_' {
            let start = at;
            while at < chars.len() && (chars[at].is_alphanumeric() || chars[at] == '_') {
                at += 1;
            }
            let word: String = chars[start..at].iter().collect();
            out.push((Token::Ident(word), line));
        } else if c.is_ascii_digit() {
            while at < chars.len() && (chars[at].is_alphanumeric() || chars[at] == '_') {
                at += 1;
            }
        } else if c == ':' && next == ':' {
            out.push((Token::PathSep, line));
            at += 2;
        } else {
            out.push((Token::Punct(c), line));
            at += 1;
        }
    }
    out
}

/// The end of a raw string `r"..."` / `r#"..."#` starting at `at`.
fn raw_string_end(chars: &[char], at: usize) -> Option<usize> {
    let hashes = chars[at + 1..].iter().take_while(|&&c| c == '#').count();
    let open = at + 1 + hashes;
    if chars.get(open) != Some(&'"') {
        return None;
    }
    let mut end = open + 1;
    while end < chars.len() {
        if chars[end] == '"'
            && chars[end + 1..]
                .iter()
                .take(hashes)
                .filter(|&&c| c == '#')
                .count()
                == hashes
        {
            return Some(end + 1 + hashes);
        }
        end += 1;
    }
    Some(chars.len())
}

/// Every path `text` names: each leaf of a `use` tree, and each inline
/// path `a::b::c` (not after `::`, `.`, `$` or `in`).
fn named_paths(text: &str) -> Vec<NamedPath> {
    let tokens = tokens(text);
    let ident = |at: usize| match tokens.get(at) {
        Some((Token::Ident(word), _)) => Some(word.as_str()),
        _ => None,
    };
    let mut out = Vec::new();
    // Inline modules open: name and the brace depth inside them.
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0;
    let mut at = 0;
    while at < tokens.len() {
        let (token, line) = &tokens[at];
        match token {
            Token::Punct('{') => {
                depth += 1;
                if at >= 2 && ident(at - 2) == Some("mod") {
                    inline.push((ident(at - 1).unwrap_or_default().to_string(), depth));
                }
            }
            Token::Punct('}') => {
                if inline.last().is_some_and(|(_, open)| *open == depth) {
                    inline.pop();
                }
                depth -= 1;
            }
            _ => {}
        }
        let inline_modules: Vec<String> = inline.iter().map(|(name, _)| name.clone()).collect();
        if ident(at) == Some("use") {
            let public_use = is_public(&tokens, at);
            let end = (at..tokens.len())
                .find(|&k| tokens[k].0 == Token::Punct(';'))
                .unwrap_or(tokens.len());
            for segments in use_tree_leaves(&tokens[at + 1..end]) {
                out.push(NamedPath {
                    segments,
                    inline_modules: inline_modules.clone(),
                    public_use,
                    line: *line,
                });
            }
            at = end;
            continue;
        }
        let starts_path = ident(at).is_some()
            && tokens.get(at + 1).map(|(t, _)| t) == Some(&Token::PathSep)
            && !(at > 0
                && matches!(
                    &tokens[at - 1].0,
                    Token::PathSep | Token::Punct('.') | Token::Punct('$')
                ))
            && !(at > 0 && ident(at - 1) == Some("in"));
        if starts_path {
            let mut segments = vec![ident(at).unwrap_or_default().to_string()];
            let mut k = at + 1;
            while tokens.get(k).map(|(t, _)| t) == Some(&Token::PathSep) {
                match ident(k + 1) {
                    Some(word) => segments.push(word.to_string()),
                    None => break,
                }
                k += 2;
            }
            out.push(NamedPath {
                segments,
                inline_modules,
                public_use: false,
                line: *line,
            });
            at = k;
            continue;
        }
        at += 1;
    }
    out
}

/// Whether the item whose keyword is at `at` starts with `pub` or
/// `pub(...)`.
fn is_public(tokens: &[(Token, usize)], at: usize) -> bool {
    let mut k = at;
    if k > 0 && tokens[k - 1].0 == Token::Punct(')') {
        while k > 0 && tokens[k - 1].0 != Token::Punct('(') {
            k -= 1;
        }
        k = k.saturating_sub(1);
    }
    k > 0 && tokens[k - 1].0 == Token::Ident("pub".to_string())
}

/// The leaves of a `use` tree (the tokens after `use`, before `;`):
/// `a::{b, c::{d, self}}` → `a::b`, `a::c::d`, `a::c`; a glob names its
/// prefix; `as` names are dropped.
fn use_tree_leaves(tree: &[(Token, usize)]) -> Vec<Vec<String>> {
    fn walk(
        tree: &[(Token, usize)],
        at: &mut usize,
        prefix: &[String],
        out: &mut Vec<Vec<String>>,
    ) {
        let mut path = prefix.to_vec();
        while *at < tree.len() {
            match &tree[*at].0 {
                Token::Ident(word) if word == "as" => *at += 2,
                Token::Ident(word)
                    if word == "self" && *at > 0 && tree[*at - 1].0 != Token::PathSep =>
                {
                    *at += 1
                }
                Token::Ident(word) => {
                    path.push(word.clone());
                    *at += 1;
                }
                Token::PathSep | Token::Punct('*') => *at += 1,
                Token::Punct('{') => {
                    *at += 1;
                    while *at < tree.len() && tree[*at].0 != Token::Punct('}') {
                        walk(tree, at, &path, out);
                        if *at < tree.len() && tree[*at].0 == Token::Punct(',') {
                            *at += 1;
                        }
                    }
                    *at += 1;
                    return;
                }
                _ => break,
            }
        }
        out.push(path);
    }
    let mut out = Vec::new();
    let mut at = 0;
    walk(tree, &mut at, &[], &mut out);
    out
}

/// The import graph among the nodes of one folder.
struct Graph {
    /// Node → node it imports → the first reference that says so.
    edges: BTreeMap<String, BTreeMap<String, String>>,
}

/// The node of `file` in the graph of `folder`: its path's first part
/// below the folder (`name.rs`, or `name/` for a subfolder); `None`
/// outside the folder.
fn node_of(file: &str, folder: &str) -> Option<String> {
    let below = match folder {
        "" => file,
        _ => file.strip_prefix(folder)?.strip_prefix('/')?,
    };
    Some(match below.split_once('/') {
        Some((subfolder, _)) => format!("{subfolder}/"),
        None => below.to_string(),
    })
}

/// Fails, printing the circle, when any two files anywhere below
/// `src/<folder>` import each other in a circle: every file is a node, and
/// an item named through a `mod.rs`'s re-export counts as an import of
/// the file that defines it (the re-export itself does not count).
fn assert_files_acyclic(folder: &str) {
    let graph = file_graph(&crate_sources(), folder);
    if let Some(cycle) = graph.find_cycle(None) {
        panic!("src/{folder}/ (file by file): {}", graph.describe(&cycle));
    }
}

/// The graph of every file below `src/<folder>`, references through a
/// `mod.rs`'s `pub use` followed to the file the item comes from.
fn file_graph(sources: &[(String, String)], folder: &str) -> Graph {
    let references = references(sources);
    // (mod.rs, item it re-exports) → the file the item comes from.
    let mut reexports: BTreeMap<(String, String), String> = BTreeMap::new();
    for (file, found) in &references {
        for reference in found.iter().filter(|r| r.reexport) {
            if let Some(name) = reference.text.rsplit("::").next() {
                reexports.insert((file.clone(), name.to_string()), reference.target.clone());
            }
        }
    }
    let through_reexports = |reference: &Reference| {
        let mut target = reference.target.clone();
        if let Some(item) = &reference.item {
            // Chains of re-exports are short; the bound only guards loops.
            for _ in 0..8 {
                match reexports.get(&(target.clone(), item.clone())) {
                    Some(next) if *next != target => target = next.clone(),
                    _ => break,
                }
            }
        }
        target
    };
    let below = |file: &str| folder.is_empty() || file.starts_with(&format!("{folder}/"));
    let mut edges: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for (file, found) in &references {
        if !below(file) {
            continue;
        }
        let targets = edges.entry(file.clone()).or_default();
        for reference in found.iter().filter(|r| !r.reexport) {
            let to = through_reexports(reference);
            if to != *file && below(&to) {
                let evidence = format!("{file}:{} `{}`", reference.line, reference.text);
                targets.entry(to).or_insert(evidence);
            }
        }
    }
    Graph { edges }
}

/// The graph of `src/<folder>` (`""`: `src/` itself).
fn folder_graph(sources: &[(String, String)], folder: &str) -> Graph {
    let mut edges: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for (file, found) in references(sources) {
        let Some(from) = node_of(&file, folder) else {
            continue;
        };
        let targets = edges.entry(from.clone()).or_default();
        for reference in found.iter().filter(|r| !r.reexport) {
            match node_of(&reference.target, folder) {
                Some(to) if to != from => {
                    let evidence = format!("{file}:{} `{}`", reference.line, reference.text);
                    targets.entry(to).or_insert(evidence);
                }
                _ => {}
            }
        }
    }
    Graph { edges }
}

impl Graph {
    /// A graph from `(from, to)` pairs.
    #[cfg(test)]
    fn of(pairs: &[(&str, &str)]) -> Graph {
        let mut edges: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
        for (from, to) in pairs {
            edges
                .entry(from.to_string())
                .or_default()
                .insert(to.to_string(), String::new());
        }
        Graph { edges }
    }

    /// A circle of imports, first node repeated at the end, among `only`
    /// (all nodes when `None`), found by depth-first search.
    fn find_cycle(&self, only: Option<&[&str]>) -> Option<Vec<String>> {
        let keep = |node: &str| only.is_none_or(|nodes| nodes.contains(&node));
        let mut finished = BTreeSet::new();
        for start in self.edges.keys().filter(|n| keep(n)) {
            let mut path = Vec::new();
            if let Some(cycle) = self.visit(start, &keep, &mut path, &mut finished) {
                return Some(cycle);
            }
        }
        None
    }

    fn visit(
        &self,
        node: &str,
        keep: &dyn Fn(&str) -> bool,
        path: &mut Vec<String>,
        finished: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(open) = path.iter().position(|n| n == node) {
            let mut cycle = path[open..].to_vec();
            cycle.push(node.to_string());
            return Some(cycle);
        }
        if finished.contains(node) {
            return None;
        }
        path.push(node.to_string());
        for next in self.edges.get(node).into_iter().flat_map(|e| e.keys()) {
            if keep(next) {
                if let Some(cycle) = self.visit(next, keep, path, finished) {
                    return Some(cycle);
                }
            }
        }
        path.pop();
        finished.insert(node.to_string());
        None
    }

    /// `a → b → a`, then each step's first reference.
    fn describe(&self, cycle: &[String]) -> String {
        let mut out = format!("import circle {}", cycle.join(" → "));
        for step in cycle.windows(2) {
            let evidence = &self.edges[&step[0]][&step[1]];
            let _ = write!(out, "\n  {} → {}: {evidence}", step[0], step[1]);
        }
        out
    }
}

#[cfg(test)]
mod checker {
    use super::*;

    fn sources(files: &[(&str, &str)]) -> Vec<(String, String)> {
        files
            .iter()
            .map(|(file, text)| (file.to_string(), text.to_string()))
            .collect()
    }

    #[test]
    fn a_reexport_is_followed_to_the_file_that_defines_the_item() {
        let files = sources(&[
            ("lib.rs", "mod s;"),
            ("s/mod.rs", "mod a;\nmod b;\npub use a::Thing;"),
            ("s/a.rs", "pub struct Thing;\nfn f() { crate::s::b::go(); }"),
            ("s/b.rs", "pub fn go() {}\nfn g(_: crate::s::Thing) {}"),
        ]);
        let graph = file_graph(&files, "s");
        assert!(graph.edges["s/b.rs"].contains_key("s/a.rs"));
        assert!(
            graph.find_cycle(None).is_some(),
            "a.rs → b.rs → (via mod.rs) a.rs"
        );
    }

    #[test]
    fn a_circle_is_found_and_a_line_is_not() {
        let circle = Graph::of(&[
            ("a.rs", "b.rs"),
            ("b.rs", "c/"),
            ("c/", "a.rs"),
            ("d.rs", "a.rs"),
        ]);
        let cycle = circle.find_cycle(None).expect("the circle");
        assert_eq!(cycle.first(), cycle.last());
        assert_eq!(cycle.len(), 4, "{cycle:?}");
        assert!(circle.find_cycle(Some(&["a.rs", "b.rs", "d.rs"])).is_none());
        let line = Graph::of(&[("a.rs", "b.rs"), ("b.rs", "c.rs"), ("a.rs", "c.rs")]);
        assert!(line.find_cycle(None).is_none());
    }

    #[test]
    fn siblings_importing_each_other_form_a_circle() {
        let files = sources(&[
            ("lib.rs", "pub mod a;"),
            (
                "a/mod.rs",
                "mod x;\nmod y;\npub use x::X;\npub use y::{Y, self};",
            ),
            ("a/x.rs", "use super::y::Y;\npub struct X;"),
            // Inline path, in a string and a comment too (those do not count).
            (
                "a/y.rs",
                "pub struct Y;\nfn f() { let _ = \"crate::b\"; crate::a::x::X; } // super::z",
            ),
        ]);
        let graph = folder_graph(&files, "a");
        let cycle = graph.find_cycle(None).expect("x ↔ y");
        assert!(cycle.contains(&"x.rs".to_string()) && cycle.contains(&"y.rs".to_string()));
        assert!(
            graph.describe(&cycle).contains("a/y.rs:2 `crate::a::x::X`"),
            "{}",
            graph.describe(&cycle)
        );
        // The re-exports of mod.rs do not count.
        assert!(graph.edges["mod.rs"].is_empty());
    }

    #[test]
    fn a_parent_that_imports_its_child_may_not_be_imported_by_it() {
        let shared = sources(&[
            ("lib.rs", "pub mod a;"),
            ("a/mod.rs", "mod x;\npub(crate) use x::X;\npub struct Shared;"),
            ("a/x.rs", "use super::Shared;\npub struct X;\n#[cfg(test)]\nmod tests {\n    use super::*;\n}"),
        ]);
        assert!(folder_graph(&shared, "a").find_cycle(None).is_none());
        let circle = sources(&[
            ("lib.rs", "pub mod a;"),
            (
                "a/mod.rs",
                "mod x;\nfn run() { x::go(); }\npub struct Shared;",
            ),
            (
                "a/x.rs",
                "pub fn go() {}\nfn f(_: &'static super::Shared) {}",
            ),
        ]);
        assert!(folder_graph(&circle, "a").find_cycle(None).is_some());
    }

    #[test]
    fn subfolders_are_one_node() {
        let files = sources(&[
            ("lib.rs", "pub mod a;\npub mod b;"),
            ("a/mod.rs", "mod t;\nmod u;"),
            ("a/t/mod.rs", "mod leaf;\nuse crate::a::u::U;"),
            ("a/t/leaf.rs", "pub struct Leaf;"),
            ("a/u.rs", "use super::t::leaf::Leaf;\npub struct U;"),
            ("b.rs", "use crate::a::u::U;"),
        ]);
        let graph = folder_graph(&files, "a");
        assert!(graph.find_cycle(None).is_some());
        assert!(graph.find_cycle(Some(&["t/", "mod.rs"])).is_none());
        let top = folder_graph(&files, "");
        assert!(top.edges["b.rs"].contains_key("a/"));
    }
}
