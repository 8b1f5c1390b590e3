//! The shape of the house, checked on the sources:
//!
//! - at most [`MAX_CRATES`] workspace crates, and no chain of workspace
//!   crates (by their `[dependencies]`) longer than [`MAX_CHAIN`];
//! - no cycle of module imports inside a crate: a file that names another
//!   (`use crate::a::b`, `use super::x`, or a path `crate::a::f(..)` in its
//!   code) depends on it; re-exports (`pub use`) and `mod` declarations are
//!   a module's interface, not dependencies; test modules are left out;
//! - no function of library or program code longer than [`MAX_FN_LINES`]
//!   lines, unless the comment above it says it is a numerical kernel and
//!   why.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_CRATES: usize = 20;
const MAX_CHAIN: usize = 7;
const MAX_FN_LINES: usize = 150;
/// What the comment above a longer function must say.
const KERNEL: &str = "numerical kernel";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every workspace crate's folder, by package name.
fn crates() -> BTreeMap<String, PathBuf> {
    let mut out = BTreeMap::new();
    for entry in std::fs::read_dir(root().join("crates")).unwrap() {
        let dir = entry.unwrap().path();
        let Ok(text) = std::fs::read_to_string(dir.join("Cargo.toml")) else {
            continue;
        };
        let manifest: toml::Table = text.parse().unwrap();
        let name = manifest["package"]["name"].as_str().unwrap().to_string();
        out.insert(name, dir);
    }
    out
}

/// The workspace crates each crate depends on (not for its tests).
fn dependencies(crates: &BTreeMap<String, PathBuf>) -> BTreeMap<String, Vec<String>> {
    crates
        .iter()
        .map(|(name, dir)| {
            let text = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
            let manifest: toml::Table = text.parse().unwrap();
            let deps = manifest
                .get("dependencies")
                .and_then(|d| d.as_table())
                .map(|t| {
                    t.keys()
                        .filter(|k| crates.contains_key(*k))
                        .cloned()
                        .collect()
                })
                .unwrap_or_default();
            (name.clone(), deps)
        })
        .collect()
}

/// The longest chain of crates from `name` down, itself included.
fn chain(name: &str, deps: &BTreeMap<String, Vec<String>>) -> Vec<String> {
    let longest = deps[name]
        .iter()
        .map(|d| chain(d, deps))
        .max_by_key(Vec::len)
        .unwrap_or_default();
    let mut out = vec![name.to_string()];
    out.extend(longest);
    out
}

#[test]
fn the_house_is_small_and_shallow() {
    let crates = crates();
    assert!(
        crates.len() <= MAX_CRATES,
        "{} workspace crates (at most {MAX_CRATES}): {:?}",
        crates.len(),
        crates.keys()
    );
    let deps = dependencies(&crates);
    for name in crates.keys() {
        let c = chain(name, &deps);
        assert!(
            c.len() <= MAX_CHAIN,
            "a chain of {} crates (at most {MAX_CHAIN}): {}",
            c.len(),
            c.join(" -> ")
        );
    }
}

/// The source files of library and program code of a crate (`src/`).
fn sources(dir: &Path) -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    let src = dir.join("src");
    if src.is_dir() {
        walk(&src, &mut out);
    }
    out.sort();
    out
}

/// The module path of a file under `src` (`lib.rs` and `main.rs`: the
/// root; `a/mod.rs` and `a.rs`: `a`).
fn module_of(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap();
    let mut parts: Vec<String> = rel
        .iter()
        .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// `text` without comments, string and character literals, and test
/// modules (`#[cfg(test)]` items), so that only code is read.
fn code_only(text: &str) -> String {
    let bytes: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        let next = bytes.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < bytes.len() && bytes[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            i += 2;
            while i + 1 < bytes.len() && !(bytes[i] == '*' && bytes[i + 1] == '/') {
                if bytes[i] == '\n' {
                    out.push('\n');
                }
                i += 1;
            }
            i += 2;
        } else if c == '"' {
            i += 1;
            while i < bytes.len() && bytes[i] != '"' {
                if bytes[i] == '\\' {
                    i += 1;
                } else if bytes[i] == '\n' {
                    out.push('\n');
                }
                i += 1;
            }
            out.push_str("\"\"");
            i += 1;
        } else if c == 'r' && next == Some('#') && bytes.get(i + 2) == Some(&'"') {
            i += 3;
            while i + 1 < bytes.len() && !(bytes[i] == '"' && bytes[i + 1] == '#') {
                if bytes[i] == '\n' {
                    out.push('\n');
                }
                i += 1;
            }
            out.push_str("\"\"");
            i += 2;
        } else if c == '\'' && bytes.get(i + 2) == Some(&'\'') {
            out.push_str("' '");
            i += 3;
        } else if c == '\'' && next == Some('\\') {
            // An escaped character literal: quote, backslash, the escape.
            i += 3;
            while i < bytes.len() && bytes[i] != '\'' {
                i += 1;
            }
            out.push_str("' '");
            i += 1;
        } else {
            out.push(c);
            i += 1;
        }
    }
    without_test_items(&out)
}

/// `code` with every item after a `#[cfg(test)]` attribute blanked (its
/// lines kept empty, so line numbers stay).
fn without_test_items(code: &str) -> String {
    let lines: Vec<&str> = code.lines().collect();
    let mut out = Vec::with_capacity(lines.len());
    let mut i = 0;
    while i < lines.len() {
        if lines[i].trim() == "#[cfg(test)]" {
            out.push(String::new());
            i += 1;
            let mut depth = 0i64;
            let mut opened = false;
            while i < lines.len() {
                for ch in lines[i].chars() {
                    match ch {
                        '{' => {
                            depth += 1;
                            opened = true;
                        }
                        '}' => depth -= 1,
                        _ => {}
                    }
                }
                let ended =
                    (opened && depth == 0) || (!opened && lines[i].trim_end().ends_with(';'));
                out.push(String::new());
                i += 1;
                if ended {
                    break;
                }
            }
        } else {
            out.push(lines[i].to_string());
            i += 1;
        }
    }
    out.join("\n")
}

/// The paths a `use` tree names, braces expanded (`a::{b, c::d}` gives
/// `a::b` and `a::c::d`).
fn expand(tree: &str) -> Vec<String> {
    let tree: String = tree.chars().filter(|c| !c.is_whitespace()).collect();
    let Some(open) = tree.find('{') else {
        return vec![tree.split(" as ").next().unwrap_or("").to_string()];
    };
    let prefix = &tree[..open];
    let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
    let mut parts = Vec::new();
    let (mut depth, mut start) = (0, 0);
    for (i, ch) in inner.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(&inner[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&inner[start..]);
    parts
        .into_iter()
        .filter(|p| !p.is_empty())
        .flat_map(|p| expand(p).into_iter().map(move |q| format!("{prefix}{q}")))
        .collect()
}

/// The module paths (absolute, from the crate root) that the code of
/// module `at`, whose child modules are `children`, names.
fn named_paths(code: &str, at: &[String], children: &[String]) -> Vec<Vec<String>> {
    let mut raw: Vec<String> = Vec::new();
    let mut rest = code;
    // `use` items, re-exports left out.
    while let Some(pos) = rest.find("use ") {
        let before = &rest[..pos];
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let head = before[line_start..].trim();
        let after = &rest[pos + 4..];
        let end = after.find(';').unwrap_or(after.len());
        if head.is_empty() {
            raw.extend(expand(&after[..end]));
        }
        rest = &after[end.min(after.len())..];
    }
    // Paths in code (re-exports left out): from the crate root, from the
    // parent, or into a child module.
    let code = without_reexports(code);
    let code = code.as_str();
    let starts = ["crate::".to_string(), "super::".to_string()];
    let into_child = children.iter().map(|c| format!("{c}::"));
    for start in starts.into_iter().chain(into_child) {
        for (i, _) in code.match_indices(start.as_str()) {
            if i > 0 && code[..i].ends_with(|c: char| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let path: String = code[i..]
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let from_self = !path.starts_with("crate::") && !path.starts_with("super::");
            raw.push(if from_self {
                format!("self::{path}")
            } else {
                path
            });
        }
    }
    raw.into_iter()
        .filter_map(|p| {
            let segments: Vec<&str> = p.split("::").filter(|s| !s.is_empty()).collect();
            let mut path: Vec<String> = match segments.first() {
                Some(&"crate") => Vec::new(),
                Some(&"super") => at[..at.len().saturating_sub(1)].to_vec(),
                Some(&"self") => at.to_vec(),
                _ => return None,
            };
            let mut rest = &segments[1..];
            while rest.first() == Some(&"super") {
                path.pop();
                rest = &rest[1..];
            }
            path.extend(rest.iter().map(|s| s.to_string()));
            Some(path)
        })
        .collect()
}

/// `code` without its `use` items (read above) and its re-exports
/// (`pub use ...;`, `pub(crate) use ...;`).
fn without_reexports(code: &str) -> String {
    let mut out = String::with_capacity(code.len());
    let mut rest = code;
    loop {
        let next = ["pub use ", "pub(crate) use ", "pub(super) use ", "\nuse "]
            .iter()
            .filter_map(|p| rest.find(p))
            .min();
        let Some(pos) = next else {
            out.push_str(rest);
            return out;
        };
        out.push_str(&rest[..pos]);
        let end = rest[pos..].find(';').map_or(rest.len(), |e| pos + e + 1);
        rest = &rest[end..];
    }
}

/// The groups of nodes of `edges` that reach each other (the strongly
/// connected components of more than one node), each sorted.
fn cycles(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    let reach = |from: &str| -> BTreeSet<String> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.to_string()];
        while let Some(n) = stack.pop() {
            for next in edges.get(&n).into_iter().flatten() {
                if seen.insert(next.clone()) {
                    stack.push(next.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> =
        edges.keys().map(|n| (n, reach(n))).collect();
    let mut groups: BTreeSet<Vec<String>> = BTreeSet::new();
    for (n, from_n) in &reached {
        let group: Vec<String> = from_n
            .iter()
            .filter(|m| reached.get(m).is_some_and(|r| r.contains(*n)))
            .cloned()
            .collect();
        if group.len() > 1 {
            groups.insert(group);
        }
    }
    groups.into_iter().collect()
}

#[test]
fn no_module_imports_a_module_that_imports_it() {
    let mut found = Vec::new();
    for (name, dir) in crates() {
        let src = dir.join("src");
        let files = sources(&dir);
        let modules: BTreeMap<Vec<String>, String> = files
            .iter()
            .map(|f| (module_of(&src, f), f.display().to_string()))
            .collect();
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for file in &files {
            let at = module_of(&src, file);
            let code = code_only(&std::fs::read_to_string(file).unwrap());
            let me = file.display().to_string();
            let children: Vec<String> = modules
                .keys()
                .filter(|m| m.len() == at.len() + 1 && m.starts_with(&at))
                .map(|m| m[at.len()].clone())
                .collect();
            for mut path in named_paths(&code, &at, &children) {
                // The deepest module the path reaches.
                let target = loop {
                    if let Some(f) = modules.get(&path) {
                        break Some(f.clone());
                    }
                    if path.pop().is_none() {
                        break None;
                    }
                };
                if let Some(t) = target.filter(|t| *t != me) {
                    edges.entry(me.clone()).or_default().insert(t);
                }
            }
        }
        for group in cycles(&edges) {
            let short: Vec<String> = group
                .iter()
                .map(|f| {
                    Path::new(f)
                        .strip_prefix(&src)
                        .map_or(f.clone(), |p| p.display().to_string())
                })
                .collect();
            found.push(format!("{name}: {}", short.join(", ")));
        }
    }
    assert!(
        found.is_empty(),
        "files that import each other, directly or through others:\n{}",
        found.join("\n")
    );
}

#[test]
fn no_function_is_too_long_to_read() {
    let mut long = Vec::new();
    for (_, dir) in crates() {
        for file in sources(&dir) {
            let text = std::fs::read_to_string(&file).unwrap();
            let raw: Vec<&str> = text.lines().collect();
            let code = code_only(&text);
            let lines: Vec<&str> = code.lines().collect();
            let mut i = 0;
            while i < lines.len() {
                let t = lines[i].trim_start();
                let is_fn = t.starts_with("fn ")
                    || t.starts_with("pub fn ")
                    || t.starts_with("pub(crate) fn ")
                    || t.starts_with("pub(super) fn ")
                    || t.starts_with("const fn ")
                    || t.starts_with("pub const fn ");
                if !is_fn {
                    i += 1;
                    continue;
                }
                let (mut depth, mut opened, mut end) = (0i64, false, i);
                'body: for (j, l) in lines.iter().enumerate().skip(i) {
                    for ch in l.chars() {
                        match ch {
                            '{' => {
                                depth += 1;
                                opened = true;
                            }
                            '}' => depth -= 1,
                            ';' if !opened => {
                                end = j;
                                break 'body;
                            }
                            _ => {}
                        }
                        if opened && depth == 0 {
                            end = j;
                            break 'body;
                        }
                    }
                }
                let length = end + 1 - i;
                if length > MAX_FN_LINES {
                    let above: String = raw[..i]
                        .iter()
                        .rev()
                        .take_while(|l| {
                            let l = l.trim_start();
                            l.starts_with("///") || l.starts_with("//") || l.starts_with("#[")
                        })
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(" ");
                    if !above.contains(KERNEL) {
                        long.push(format!(
                            "{}:{}: {length} lines",
                            file.strip_prefix(root()).unwrap_or(&file).display(),
                            i + 1
                        ));
                    }
                }
                i = end + 1;
            }
        }
    }
    assert!(
        long.is_empty(),
        "functions over {MAX_FN_LINES} lines (split them, or say above one why it is a {KERNEL}):\n{}",
        long.join("\n")
    );
}
