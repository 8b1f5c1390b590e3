//! Model files that extend another: `extends = "base.toml"`.
//!
//! A candidate structure is usually a known model with one element more
//! (a parameter, a definition, a reset). Such a file names its base and
//! writes only what differs; [`read`] resolves the chain into one document,
//! which the model parser then reads as if it had been written out whole.
//!
//! How a file is laid over its base (documented in
//! `docs/gray-box-models.md`, "Extending a file"):
//!
//! - tables merge key by key, recursively, the file's value winning; a
//!   table whose tag (`type`, `from` or `kind`) differs from the base's
//!   replaces it whole;
//! - arrays whose entries are all tables with a `name` (parameters, modes,
//!   elements, outputs) merge by name: an entry with a base entry's name is
//!   merged into it in place, a new name is appended (an empty array
//!   replaces the base's);
//! - any other value, arrays included (states, transitions, invariants,
//!   bounds), replaces the base's;
//! - `remove = ["parameters.d2", "elements.friction", "modes.impact.definitions.kinetic"]`
//!   deletes entries of the base before the merge, each addressed by keys
//!   and names joined with dots.
//!
//! `extends` is a path relative to the directory of the file that writes it;
//! a chain holds at most [`MAX_CHAIN`] files and may not return to a file
//! already in it.

use serde_json::{Map, Value};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// The longest chain of files `extends` may follow.
pub const MAX_CHAIN: usize = 16;

/// The keys whose value names a table's variant: a table with another
/// value of one of them replaces the base's instead of merging into it.
const TAGS: [&str; 3] = ["kind", "type", "from"];

/// One file of a resolved chain.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// Its path, as reached (the base's joined to its extender's directory).
    pub path: PathBuf,
    /// Its text.
    pub text: String,
}

/// A model file with its bases laid under it.
#[derive(Debug, Clone, PartialEq)]
pub struct ResolvedFile {
    /// The merged document, without `extends` and `remove`.
    pub value: Value,
    /// The files read: the file itself first, then its base, its base's
    /// base, and so on.
    pub sources: Vec<Source>,
}

/// Why a chain of model files could not be resolved; every variant names
/// the file at fault.
#[derive(Debug, thiserror::Error)]
pub enum ExtendsError {
    /// The file itself could not be read (a base that cannot be read is a
    /// [`ExtendsError::Chain`] error of the file that extends it).
    #[error("{}: {source}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The reason.
        source: std::io::Error,
    },
    /// A file of the chain is not TOML (or, for `.json`, JSON).
    #[error("{}: {message}", path.display())]
    Syntax {
        /// The file.
        path: PathBuf,
        /// The parser's message (with its line and column).
        message: String,
    },
    /// `extends` or `remove` is written wrongly, or the chain loops or is
    /// too long.
    #[error("{}: {message}", path.display())]
    Chain {
        /// The file that writes the entry.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// Reads the model file at `path` and every base it extends, and merges
/// them. A file without `extends` comes back as it was parsed, alone in
/// `sources`.
pub fn read(path: &Path) -> Result<ResolvedFile, ExtendsError> {
    let mut sources = Vec::new();
    let value = resolve(path, &mut sources)?;
    Ok(ResolvedFile { value, sources })
}

/// The document of `path` laid over its resolved base; `sources` gets the
/// files read, in chain order.
fn resolve(path: &Path, sources: &mut Vec<Source>) -> Result<Value, ExtendsError> {
    let chain_error = |message: String| ExtendsError::Chain {
        path: sources.last().map_or(path, |s| &s.path).to_path_buf(),
        message,
    };
    if sources.len() == MAX_CHAIN {
        return Err(chain_error(format!(
            "extends: a chain of more than {MAX_CHAIN} files"
        )));
    }
    let text = std::fs::read_to_string(path).map_err(|source| match sources.last() {
        Some(extender) => ExtendsError::Chain {
            path: extender.path.clone(),
            message: format!("extends: cannot read {}: {source}", path.display()),
        },
        None => ExtendsError::Read {
            path: path.to_path_buf(),
            source,
        },
    })?;
    // Editors on Windows may save UTF-8 with a byte-order mark: not text.
    let text = match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    };
    let here = std::fs::canonicalize(path).ok();
    if here.is_some()
        && sources
            .iter()
            .any(|s| std::fs::canonicalize(&s.path).ok() == here)
    {
        return Err(chain_error(format!(
            "extends: {} is already in the chain (a loop)",
            path.display()
        )));
    }
    let mut value = parse(path, &text)?;
    sources.push(Source {
        path: path.to_path_buf(),
        text,
    });
    let Some(table) = value.as_object_mut() else {
        return Ok(value);
    };
    let Some(base) = table.remove("extends") else {
        return Ok(value);
    };
    let own_error = |message: String| ExtendsError::Chain {
        path: path.to_path_buf(),
        message,
    };
    let base = match base {
        Value::String(base) if !base.trim().is_empty() => base,
        _ => {
            return Err(own_error(
                "extends: expected the path of a model file".into(),
            ));
        }
    };
    let base_path = path.parent().unwrap_or(Path::new("")).join(base.trim());
    let base = resolve(&base_path, sources)?;
    extend(base, value).map_err(own_error)
}

/// `own`, a file's document without its `extends`, laid over `base`, the
/// resolved document of its base: the entries of `own`'s `remove` are
/// deleted from the base, then the two are merged (the rules of the
/// module's documentation). The error says what is wrong in `own`.
pub fn extend(mut base: Value, mut own: Value) -> Result<Value, String> {
    let removals = removals(own.as_object_mut().and_then(|t| t.remove("remove")))?;
    remove(&mut base, &removals)?;
    check_unique_names(&own)?;
    check_new_entries(&base, &own)?;
    merge(&mut base, own);
    Ok(base)
}

/// The keys an entry of each array merged by name needs when the base has
/// no entry of its name: without them the file's entry is most likely a
/// misspelt change of one of the base's.
const NEW_ENTRY_KEYS: [(&str, &[&str]); 4] = [
    ("parameters", &["value", "bounds"]),
    ("elements", &["type"]),
    ("modes", &["flow"]),
    ("outputs", &["value"]),
];

/// Refuses an entry of `own` that the base lacks by name and that lacks a
/// key a new entry needs ([`NEW_ENTRY_KEYS`]), naming the base's entries.
fn check_new_entries(base: &Value, own: &Value) -> Result<(), String> {
    for (array, keys) in NEW_ENTRY_KEYS {
        let Some(Value::Array(over)) = own.get(array) else {
            continue;
        };
        let known: Vec<&str> = match base.get(array) {
            Some(Value::Array(items)) => items.iter().filter_map(name_of).collect(),
            _ => Vec::new(),
        };
        let names: HashSet<&str> = known.iter().copied().collect();
        for entry in over {
            let Some(name) = name_of(entry).filter(|n| !names.contains(n)) else {
                continue;
            };
            if let Some(key) = keys.iter().find(|k| entry.get(**k).is_none()) {
                return Err(format!(
                    "[[{array}]] '{name}': the base has no entry of that name (its {array}: {}), \
                     and a new one needs `{key}`",
                    if known.is_empty() {
                        "none".to_string()
                    } else {
                        known.join(", ")
                    }
                ));
            }
        }
    }
    Ok(())
}

/// The syntax of a model file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Syntax {
    /// TOML.
    Toml,
    /// JSON.
    Json,
}

impl Syntax {
    /// The syntax of the file `path` of text `text`: by its extension,
    /// `.json` or `.toml` in any case; for any other name, JSON when the
    /// text starts with `{` (which no TOML document does), TOML otherwise.
    /// Files written under any name but `.toml` are JSON, so every model
    /// file the program writes reads back.
    pub fn of(path: &Path, text: &str) -> Self {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("json") => Syntax::Json,
            Some(e) if e.eq_ignore_ascii_case("toml") => Syntax::Toml,
            _ if text.trim_start().starts_with('{') => Syntax::Json,
            _ => Syntax::Toml,
        }
    }
}

/// The document of one file ([`Syntax::of`]).
fn parse(path: &Path, text: &str) -> Result<Value, ExtendsError> {
    let syntax = |message: String| ExtendsError::Syntax {
        path: path.to_path_buf(),
        message: message.trim().replace('\n', " "),
    };
    if Syntax::of(path, text) == Syntax::Json {
        serde_json::from_str(text).map_err(|e| syntax(json_message(&e, text)))
    } else {
        // Read straight into the JSON document, as a `toml::Table` would
        // serialise into it (datetimes as their private tables).
        toml::from_str(text).map_err(|e: toml::de::Error| syntax(e.to_string()))
    }
}

/// serde_json's message for `e` in `text`, with the reason when it
/// stopped at a `NaN` or an infinity, which JSON has no words for.
pub fn json_message(e: &serde_json::Error, text: &str) -> String {
    let line = text.lines().nth(e.line().saturating_sub(1)).unwrap_or("");
    // serde_json counts the column in bytes.
    let mut at = e.column().saturating_sub(1).min(line.len());
    while !line.is_char_boundary(at) {
        at -= 1;
    }
    // The word the parser stopped in: `nan` stops it after its `n`.
    let start = line[..at].trim_end_matches(|c: char| c.is_ascii_alphabetic() || c == '-');
    let word: String = line[start.len()..]
        .trim_start_matches('-')
        .chars()
        .take_while(char::is_ascii_alphabetic)
        .collect();
    let non_finite = ["nan", "inf", "infinity"].contains(&word.to_lowercase().as_str());
    if non_finite {
        format!("{e} (JSON has no NaN or infinity: a model's numbers are finite)")
    } else {
        e.to_string()
    }
}

/// The entries of `remove`: a list of dotted paths.
fn removals(value: Option<Value>) -> Result<Vec<String>, String> {
    let expected = || "remove: expected a list of entries such as \"parameters.d2\"".to_string();
    match value {
        None => Ok(Vec::new()),
        Some(Value::Array(items)) => items
            .into_iter()
            .map(|item| match item {
                Value::String(s) if !s.trim().is_empty() => Ok(s.trim().to_string()),
                _ => Err(expected()),
            })
            .collect(),
        Some(_) => Err(expected()),
    }
}

/// The `name` of a table, if it has a string one.
fn name_of(value: &Value) -> Option<&str> {
    value.get("name").and_then(Value::as_str)
}

/// True when every entry of `items` is a table with a name: such arrays
/// merge by name.
fn by_name(items: &[Value]) -> bool {
    items.iter().all(|v| name_of(v).is_some())
}

/// True when the array `over` merges into `base` by name: both hold only
/// named tables, and `over` holds some (an empty array replaces the base's).
fn merges_by_name(base: &[Value], over: &[Value]) -> bool {
    !over.is_empty() && by_name(base) && by_name(over)
}

/// True when `base` and `over` are variants of the same thing: no tag key
/// of [`TAGS`] has two different values.
fn same_variant(base: &Map<String, Value>, over: &Map<String, Value>) -> bool {
    TAGS.iter()
        .all(|tag| match (base.get(*tag), over.get(*tag)) {
            (Some(a), Some(b)) => a == b,
            _ => true,
        })
}

/// Lays `over` over `base` (the rules of the module's documentation).
fn merge(base: &mut Value, over: Value) {
    match (base, over) {
        (Value::Object(base), Value::Object(over)) if same_variant(base, &over) => {
            for (key, value) in over {
                match base.get_mut(&key) {
                    Some(slot) => merge(slot, value),
                    None => {
                        base.insert(key, value);
                    }
                }
            }
        }
        (Value::Array(base), Value::Array(over)) if merges_by_name(base, &over) => {
            // The first entry of each name, as a search from the start finds.
            let mut first = first_by_name(base);
            for entry in over {
                match name_of(&entry).and_then(|n| first.get(n)) {
                    Some(&i) => merge(&mut base[i], entry),
                    None => {
                        if let Some(n) = name_of(&entry) {
                            first.insert(n.to_owned(), base.len());
                        }
                        base.push(entry);
                    }
                }
            }
        }
        (slot, over) => *slot = over,
    }
}

/// Refuses a file that names two entries of one array alike: merged by
/// name, the second would silently amend the first.
fn check_unique_names(value: &Value) -> Result<(), String> {
    match value {
        Value::Object(table) => {
            for (key, v) in table {
                if let Value::Array(items) = v
                    && by_name(items)
                {
                    let mut seen = std::collections::BTreeSet::new();
                    if let Some(twice) = items.iter().filter_map(name_of).find(|n| !seen.insert(*n))
                    {
                        return Err(format!("{key}: two entries named `{twice}`"));
                    }
                }
                check_unique_names(v)?;
            }
            Ok(())
        }
        Value::Array(items) => items.iter().try_for_each(check_unique_names),
        _ => Ok(()),
    }
}

/// The position of the first entry of each name in `items`.
fn first_by_name(items: &[Value]) -> HashMap<String, usize> {
    let mut first = HashMap::with_capacity(items.len());
    for (i, item) in items.iter().enumerate() {
        if let Some(n) = name_of(item) {
            first.entry(n.to_owned()).or_insert(i);
        }
    }
    first
}

/// The entries `remove` deletes, as a tree of their keys and names: a
/// node marked `removed` (by the path of `remove` that names it) goes with
/// everything under it.
#[derive(Default)]
struct Removals<'p> {
    removed: Option<&'p str>,
    under: HashMap<&'p str, Removals<'p>>,
}

/// Deletes the entries `paths` (keys and names joined by dots) from
/// `base`, as if one after the other: an entry the base does not have, or
/// that an earlier one deleted (itself, listed twice, or with what holds
/// it), is an error naming it. Each path is looked up once, by name, and each table or
/// array is rewritten once, however many entries it loses. A path is
/// looked up in the base before it is followed, so the walks go no deeper
/// than the base (whose parser limits its nesting).
fn remove(base: &mut Value, paths: &[String]) -> Result<(), String> {
    let mut removals = Removals::default();
    // The first entry of each name in the arrays looked into, by array.
    let mut arrays: HashMap<*const Vec<Value>, HashMap<String, usize>> = HashMap::new();
    for path in paths {
        let missing = || format!("remove: the base has no entry `{path}`");
        let parts: Vec<&str> = path.split('.').map(str::trim).collect();
        let mut at: &Value = base;
        for part in &parts {
            at = match at {
                Value::Object(table) => table.get(*part),
                Value::Array(items) => arrays
                    .entry(std::ptr::from_ref(items))
                    .or_insert_with(|| first_by_name(items))
                    .get(*part)
                    .map(|&i| &items[i]),
                _ => None,
            }
            .ok_or_else(missing)?;
        }
        // Deleted already: by this path listed before, or with an entry
        // that holds it.
        let gone = |by: &str| {
            if by == path {
                format!("remove: `{path}` is listed twice")
            } else {
                format!("remove: `{path}` is already removed, with `{by}`")
            }
        };
        let mut node = &mut removals;
        for part in &parts {
            if let Some(by) = node.removed {
                return Err(gone(by));
            }
            node = node.under.entry(part).or_default();
        }
        if let Some(by) = node.removed {
            return Err(gone(by));
        }
        node.removed = Some(path);
    }
    delete(base, &removals);
    Ok(())
}

/// Deletes what `removals` marks under `value`.
fn delete(value: &mut Value, removals: &Removals) {
    match value {
        Value::Object(table) => {
            for (key, node) in &removals.under {
                if node.removed.is_some() {
                    table.remove(*key);
                } else if let Some(v) = table.get_mut(*key) {
                    delete(v, node);
                }
            }
        }
        Value::Array(items) => {
            let first = first_by_name(items);
            let mut gone = HashSet::new();
            for (name, node) in &removals.under {
                if node.removed.is_some() {
                    gone.insert(*name);
                } else if let Some(&i) = first.get(*name) {
                    delete(&mut items[i], node);
                }
            }
            if !gone.is_empty() {
                items.retain(|item| name_of(item).is_none_or(|n| !gone.contains(n)));
            }
        }
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    /// A directory of its own under the system's temporary directory.
    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("hysid-extends-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    /// A model's syntax by its name, any case, or else by its text; a
    /// JSON `NaN` or infinity is named as what JSON lacks.
    #[test]
    fn the_syntax_of_a_file_and_json_without_non_finite_numbers() {
        let of = |name: &str, text: &str| Syntax::of(Path::new(name), text);
        assert_eq!(of("m.JSON", "kind = 1"), Syntax::Json);
        assert_eq!(of("m.Toml", "{}"), Syntax::Toml);
        assert_eq!(of("m", " {\"kind\": 1}"), Syntax::Json);
        assert_eq!(of("m.txt", "kind = 1"), Syntax::Toml);
        let message =
            |value: &str| match parse(Path::new("m.json"), &format!("{{\"a\": [1, {value}]}}")) {
                Err(ExtendsError::Syntax { message, .. }) => message,
                other => panic!("{value}: {other:?}"),
            };
        for value in [
            "NaN",
            "nan",
            "Infinity",
            "-Infinity",
            "inf",
            "\"Rückfahrt\", NaN",
        ] {
            assert!(
                message(value).contains("JSON has no NaN or infinity"),
                "{value}"
            );
        }
        for value in ["1.5x", "true x", "nul"] {
            assert!(!message(value).contains("NaN"), "{value}");
        }
    }

    const BASE: &str = r#"
kind = "gray_box"
name = "base"
states = ["y", "v"]
[[parameters]]
name = "a"
value = 1.0
bounds = [0.0, 2.0]
[[parameters]]
name = "b"
value = 2.0
[definitions]
F = "a*y"
G = "b"
[[modes]]
name = "free"
flow = { y = "v", v = "F" }
definitions = { F = "a", K = "b" }
[[elements]]
type = "dry_friction"
name = "friction"
kinetic = "G"
[[elements]]
type = "stop"
name = "upper"
at = "0"
"#;

    #[test]
    fn a_file_is_laid_over_its_base_by_keys_and_names() {
        let d = dir("merge");
        write(&d, "base.toml", BASE);
        let child = write(
            &d,
            "child.toml",
            r#"
extends = "base.toml"
name = "child"
states = ["y", "v", "z"]
remove = ["parameters.b", "modes.free.definitions.K", "elements.upper"]
[[parameters]]
name = "a"
bounds = [0.0, 5.0]
[[parameters]]
name = "c"
value = 3.0
bounds = [0.0, 5.0]
[definitions]
G = "c"
[[modes]]
name = "free"
flow = { z = "0" }
[[elements]]
type = "lugre"
name = "friction"
"#,
        );
        let r = read(&child).unwrap();
        assert_eq!(r.sources.len(), 2);
        assert_eq!(r.sources[1].path, d.join("base.toml"));
        assert_eq!(
            r.value,
            json!({
                "kind": "gray_box",
                "name": "child",
                "states": ["y", "v", "z"],
                "parameters": [
                    {"name": "a", "value": 1.0, "bounds": [0.0, 5.0]},
                    {"name": "c", "value": 3.0, "bounds": [0.0, 5.0]}
                ],
                "definitions": {"F": "a*y", "G": "c"},
                "modes": [{
                    "name": "free",
                    "flow": {"y": "v", "v": "F", "z": "0"},
                    "definitions": {"F": "a"}
                }],
                "elements": [{"type": "lugre", "name": "friction"}]
            })
        );
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn removals_apply_as_if_one_after_the_other() {
        let base = json!({
            "parameters": [{"name": "a", "v": 1}, {"name": "b", "v": 2}, {"name": "a", "v": 3}],
            "modes": [{"name": "m", "definitions": {"F": "x", "G": "y"}}],
        });
        let removing = |paths: &[&str]| extend(base.clone(), json!({ "remove": paths }));
        // Every entry of a name goes; a child may go before what holds it.
        assert_eq!(
            removing(&["modes.m.definitions.F", "parameters.a", "modes.m"]).unwrap(),
            json!({"parameters": [{"name": "b", "v": 2}], "modes": []})
        );
        // An entry already deleted, itself or with what holds it, is named
        // so.
        for (paths, said) in [
            (
                &["parameters.b", "parameters.b"][..],
                "remove: `parameters.b` is listed twice",
            ),
            (
                &["modes.m", "modes.m.definitions.G"][..],
                "remove: `modes.m.definitions.G` is already removed, with `modes.m`",
            ),
            (
                &["parameters.b.v", "parameters.b.v"][..],
                "remove: `parameters.b.v` is listed twice",
            ),
            (&["modes.m.definitions"][..], ""),
        ] {
            match removing(paths) {
                Ok(_) => assert!(said.is_empty(), "{paths:?}"),
                Err(e) => assert_eq!(e, said),
            }
        }
        // A path is followed through the first entry of a name.
        assert!(removing(&["parameters.a.v"]).is_ok());
        assert_eq!(
            removing(&["parameters.a.w"]).unwrap_err(),
            "remove: the base has no entry `parameters.a.w`"
        );
    }

    #[test]
    fn a_new_entry_without_what_a_new_one_needs_is_named_with_the_base_s() {
        let base = json!({
            "parameters": [{"name": "f1", "value": 1.0, "bounds": [0, 2]}],
            "elements": [{"name": "friction", "type": "dry_friction"}],
        });
        let misspelt = |over: Value| extend(base.clone(), over).unwrap_err();
        assert_eq!(
            misspelt(json!({"elements": [{"name": "frictio", "kinetic": "2*f1"}]})),
            "[[elements]] 'frictio': the base has no entry of that name (its elements: \
             friction), and a new one needs `type`"
        );
        let e = misspelt(json!({"parameters": [{"name": "f11", "bounds": [0, 3]}]}));
        assert!(
            e.ends_with("(its parameters: f1), and a new one needs `value`"),
            "{e}"
        );
        let e = misspelt(json!({"parameters": [{"name": "f11", "value": 2.0}]}));
        assert!(e.ends_with("and a new one needs `bounds`"), "{e}");
        let e = misspelt(json!({"modes": [{"name": "free"}]}));
        assert!(e.contains("(its modes: none)"), "{e}");
        // Changes of the base's entries, and complete new ones, merge.
        let over = json!({
            "parameters": [
                {"name": "f1", "bounds": [0, 3]},
                {"name": "f2", "value": 0.0, "bounds": [0, 1]}
            ],
            "elements": [{"name": "friction", "kinetic": "f1"}],
        });
        assert!(extend(base.clone(), over).is_ok());
    }

    #[test]
    fn large_arrays_merge_and_lose_entries_by_name() {
        // 50 000 parameters: every other one removed, every third amended,
        // and as many new ones appended.
        let n = 50_000;
        let base = json!({
            "parameters": (0..n).map(|i| json!({"name": format!("p{i}"), "value": i})).collect::<Vec<_>>()
        });
        let remove: Vec<String> = (0..n)
            .step_by(2)
            .map(|i| format!("parameters.p{i}"))
            .collect();
        let over: Vec<Value> = (0..n)
            .filter(|i| i % 3 == 0 && i % 2 == 1)
            .map(|i| json!({"name": format!("p{i}"), "bounds": [0, i]}))
            .chain(
                (n..2 * n).map(|i| json!({"name": format!("p{i}"), "value": i, "bounds": [0, i]})),
            )
            .collect();
        let merged = extend(base, json!({"remove": remove, "parameters": over})).unwrap();
        let params = merged["parameters"].as_array().unwrap();
        assert_eq!(params.len(), n / 2 + n);
        assert_eq!(params[0], json!({"name": "p1", "value": 1}));
        assert_eq!(
            params[1],
            json!({"name": "p3", "value": 3, "bounds": [0, 3]})
        );
        assert_eq!(
            params[n / 2],
            json!({"name": format!("p{n}"), "value": n, "bounds": [0, n]})
        );
    }

    #[test]
    fn an_empty_array_clears_the_base_s() {
        let base = json!({"elements": [{"name": "friction"}], "states": ["y"]});
        let own = json!({"elements": [], "states": []});
        assert_eq!(extend(base, own.clone()).unwrap(), own);
    }

    #[test]
    fn a_file_without_extends_is_returned_as_parsed() {
        let d = dir("plain");
        let base = write(&d, "base.toml", BASE);
        let r = read(&base).unwrap();
        let direct: toml::Table = BASE.parse().unwrap();
        assert_eq!(r.value, serde_json::to_value(direct).unwrap());
        assert_eq!(r.sources.len(), 1);
        std::fs::remove_dir_all(d).unwrap();
    }

    /// Every kind of TOML value (datetimes, non-finite floats, nested and
    /// inline tables, arrays of tables) reads into the document that the
    /// file parsed as a `toml::Table` serialises into.
    #[test]
    fn toml_values_read_as_a_table_serialises_them() {
        let text = r#"
i = -7
big = 9223372036854775807
f = 1.5e-3
inf = inf
nan = nan
b = true
s = "a \"quoted\" \u00e9"
lit = 'C:\raw'
odt = 1979-05-27T07:32:00-08:00
ldt = 1979-05-27T07:32:00
ld = 1979-05-27
lt = 07:32:00.5
mixed = [1, 2.0, "x", [3], { k = 1979-05-27 }]
inline = { a = 1, b = { c = [] } }
"dotted.key" = 1
a.b.c = 2
[t]
x = 1
[[arr]]
name = "one"
[[arr]]
name = "two"
[arr.sub]
y = 1e300
"#;
        let path = Path::new("x.toml");
        let table: toml::Table = text.parse().unwrap();
        assert_eq!(
            parse(path, text).unwrap(),
            serde_json::to_value(table).unwrap()
        );
        // Not TOML: the parser's message, on one line.
        let e = parse(path, "a = \n[b\n").unwrap_err().to_string();
        let table_error = "a = \n[b\n".parse::<toml::Table>().unwrap_err();
        assert_eq!(
            e,
            format!(
                "x.toml: {}",
                table_error.to_string().trim().replace('\n', " ")
            )
        );
    }

    #[test]
    fn chains_resolve_in_order_and_json_bases_are_read() {
        let d = dir("chain");
        write(&d, "a.json", r#"{"kind": "gray_box", "name": "a", "x": 1}"#);
        std::fs::create_dir_all(d.join("sub")).unwrap();
        write(
            &d,
            "sub/b.toml",
            "extends = \"../a.json\"\nname = \"b\"\ny = 2\n",
        );
        let c = write(&d, "c.toml", "extends = \"sub/b.toml\"\nx = 3\n");
        let r = read(&c).unwrap();
        assert_eq!(
            r.value,
            json!({"kind": "gray_box", "name": "b", "x": 3, "y": 2})
        );
        assert_eq!(r.sources.len(), 3);
        std::fs::remove_dir_all(d).unwrap();
    }

    #[test]
    fn broken_chains_name_the_file_at_fault() {
        let d = dir("broken");
        write(&d, "base.toml", BASE);
        let cases = [
            (
                "loop.toml",
                "extends = \"loop.toml\"\n",
                "loop.toml",
                "a loop",
            ),
            (
                "missing.toml",
                "extends = \"none.toml\"\n",
                "missing.toml",
                "none.toml: No such file",
            ),
            (
                "number.toml",
                "extends = 3\n",
                "number.toml",
                "expected the path",
            ),
            (
                "gone.toml",
                "extends = \"base.toml\"\nremove = [\"parameters.zz\"]\n",
                "gone.toml",
                "no entry `parameters.zz`",
            ),
            (
                "list.toml",
                "extends = \"base.toml\"\nremove = \"parameters.a\"\n",
                "list.toml",
                "expected a list",
            ),
            (
                "twice.toml",
                "extends = \"base.toml\"\n[[parameters]]\nname = \"c\"\n[[parameters]]\nname = \"c\"\n",
                "twice.toml",
                "two entries named `c`",
            ),
            (
                "syntax.toml",
                "extends = \"base.toml\"\nname = \n",
                "syntax.toml",
                "line 2",
            ),
        ];
        for (file, text, names, says) in cases {
            let p = write(&d, file, text);
            let e = read(&p).unwrap_err().to_string();
            assert!(e.contains(names) && e.contains(says), "{file}: {e}");
            assert!(!e.contains('\n'), "{file}: {e}");
        }
        std::fs::remove_dir_all(d).unwrap();
    }

    use proptest::prelude::*;

    /// Documents shaped like model files: tables with a few keys (one of
    /// them a tag), whose values are numbers, texts, lists, tables and
    /// arrays of named tables with unique names.
    fn document() -> impl Strategy<Value = Value> {
        let leaf = prop_oneof![
            (0i64..3).prop_map(Value::from),
            prop::sample::select(vec!["x", "y"]).prop_map(Value::from),
            prop::collection::vec(0i64..3, 0..3).prop_map(Value::from),
        ];
        let table = |inner: BoxedStrategy<Value>| {
            prop::collection::btree_map(
                prop::sample::select(vec!["a", "b", "c", "type"]),
                inner,
                0..4,
            )
            .prop_map(|m| Value::Object(m.into_iter().map(|(k, v)| (k.to_string(), v)).collect()))
        };
        leaf.prop_recursive(2, 24, 4, move |inner| {
            let named = prop::collection::btree_map(
                prop::sample::select(vec!["p", "q", "r"]),
                table(inner.clone().boxed()),
                0..3,
            )
            .prop_map(|m| {
                Value::Array(
                    m.into_iter()
                        .map(|(name, mut t)| {
                            t.as_object_mut()
                                .unwrap()
                                .insert("name".into(), name.into());
                            t
                        })
                        .collect(),
                )
            });
            prop_oneof![table(inner.boxed()), named]
        })
        .prop_filter("a table at the top", Value::is_object)
    }

    /// Checks that `merged` holds every value `own` writes and every value
    /// of `base` that `own` leaves alone.
    fn laid_over(base: &Value, own: &Value, merged: &Value) -> Result<(), String> {
        let fail = || Err(format!("base {base}\nown {own}\nmerged {merged}"));
        match (base, own) {
            (Value::Object(b), Value::Object(o)) if same_variant(b, o) => {
                let Value::Object(m) = merged else {
                    return fail();
                };
                for (k, v) in b.iter().filter(|(k, _)| !o.contains_key(*k)) {
                    if m.get(k) != Some(v) {
                        return fail();
                    }
                }
                for (k, v) in o {
                    match (b.get(k), m.get(k)) {
                        (Some(bv), Some(mv)) => laid_over(bv, v, mv)?,
                        (None, Some(mv)) if mv == v => {}
                        _ => return fail(),
                    }
                }
                (m.len()
                    == b.keys()
                        .chain(o.keys())
                        .collect::<std::collections::BTreeSet<_>>()
                        .len())
                .then_some(())
                .map_or_else(fail, Ok)
            }
            (Value::Array(b), Value::Array(o)) if merges_by_name(b, o) => {
                let Value::Array(m) = merged else {
                    return fail();
                };
                let find = |items: &[Value], n: &str| {
                    items.iter().find(|x| name_of(x) == Some(n)).cloned()
                };
                let names: Vec<&str> = b.iter().chain(o).filter_map(name_of).collect();
                let mut order: Vec<&str> = Vec::new();
                for n in names {
                    if !order.contains(&n) {
                        order.push(n);
                    }
                }
                if m.iter().filter_map(name_of).collect::<Vec<_>>() != order {
                    return fail();
                }
                for n in order {
                    let mv = find(m, n).unwrap();
                    match (find(b, n), find(o, n)) {
                        (Some(bv), Some(ov)) => laid_over(&bv, &ov, &mv)?,
                        (Some(bv), None) if bv == mv => {}
                        (None, Some(ov)) if ov == mv => {}
                        _ => return fail(),
                    }
                }
                Ok(())
            }
            _ if merged == own => Ok(()),
            _ => fail(),
        }
    }

    proptest! {
        /// The merge keeps what the file does not write, takes what it
        /// writes, keeps the base's order of named entries and appends new
        /// ones; an empty file, or the base itself, gives the base back.
        #[test]
        fn a_file_is_laid_over_any_base(base in document(), own in document()) {
            let merged = extend(base.clone(), own.clone()).unwrap();
            if let Err(e) = laid_over(&base, &own, &merged) {
                prop_assert!(false, "{}", e);
            }
            prop_assert_eq!(extend(base.clone(), json!({})).unwrap(), base.clone());
            prop_assert_eq!(extend(base.clone(), base.clone()).unwrap(), base);
        }

        /// A removed entry is gone, and nothing else changes.
        #[test]
        fn remove_deletes_exactly_the_entry(base in document(), pick in any::<prop::sample::Index>()) {
            let Value::Object(table) = &base else { unreachable!() };
            prop_assume!(!table.is_empty());
            let key = table.keys().nth(pick.index(table.len())).unwrap().clone();
            let merged = extend(base.clone(), json!({ "remove": [key.clone()] })).unwrap();
            let mut expected = table.clone();
            expected.remove(&key);
            prop_assert_eq!(merged, Value::Object(expected));
            let twice = extend(base, json!({ "remove": [key.clone(), key] }));
            prop_assert!(twice.is_err());
        }
    }

    #[test]
    fn a_chain_longer_than_the_bound_is_refused() {
        let d = dir("long");
        write(&d, "f0.toml", "kind = \"gray_box\"\n");
        for i in 1..=MAX_CHAIN {
            write(
                &d,
                &format!("f{i}.toml"),
                &format!("extends = \"f{}.toml\"\n", i - 1),
            );
        }
        let ok = read(&d.join(format!("f{}.toml", MAX_CHAIN - 1))).unwrap();
        assert_eq!(ok.sources.len(), MAX_CHAIN);
        let e = read(&d.join(format!("f{MAX_CHAIN}.toml")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("more than 16 files"), "{e}");
        std::fs::remove_dir_all(d).unwrap();
    }
}
