//! Where a model file that does not deserialize goes wrong: the line, and
//! for TOML the entry.
//!
//! [`super::Model`] is tagged by `kind` inside the document, so serde reads the
//! whole document into a buffer before the kind's struct reads it; an error
//! raised there has lost the parser's position (the `toml` crate's span,
//! serde_json's line and column). Here the text is read again, straight
//! into the struct of its kind, with the tag hidden from it: the parser
//! then raises the same error with its position.

use hysid_graybox::GrayBoxModel;
use hysid_graybox::extends::Syntax;
use hysid_mechanical::MechanicalModel;
use hysid_model::model::{HybridAutomaton, PwarxModel};
use serde::Deserialize;
use serde::de::{self, DeserializeSeed, Deserializer, IgnoredAny, MapAccess, Visitor};
use std::fmt;
use std::ops::Range;
use toml::Spanned;
use toml::de::DeValue;

/// Why a model file's text does not deserialize.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct ReadError {
    /// The parser's message, without position.
    pub message: String,
    /// The keys leading to the value at fault (`parameters.value`); TOML
    /// only.
    pub entry: Option<String>,
    /// The 1-based line of the error; `None` when the parser points at
    /// the whole document (a missing top-level field).
    pub line: Option<usize>,
}

impl ReadError {
    /// The message with its entry first (`parameters.value: invalid type:
    /// ...`).
    pub fn describe(&self) -> String {
        let message = plain(&self.message);
        match &self.entry {
            Some(entry) => format!("{entry}: {message}"),
            None => message,
        }
    }
}

/// A parser's message in a model author's words: Rust's type names and
/// serde's `sequence` and `map` as numbers, lists and tables.
fn plain(message: &str) -> String {
    const WORDS: [(&str, &str); 12] = [
        ("expected f64", "expected a number"),
        ("expected f32", "expected a number"),
        ("expected u64", "expected a whole number >= 0"),
        ("expected u32", "expected a whole number >= 0"),
        ("expected usize", "expected a whole number >= 0"),
        ("expected u16", "expected a whole number >= 0"),
        ("expected u8", "expected a whole number >= 0"),
        ("expected i64", "expected a whole number"),
        ("expected a sequence", "expected a list"),
        ("expected a map", "expected a table"),
        ("invalid type: sequence", "invalid type: list"),
        ("invalid type: map", "invalid type: table"),
    ];
    WORDS.iter().fold(message.to_string(), |m, (rust, plain)| {
        m.replace(rust, plain)
    })
}

/// The first error of reading a file's `text` as a model of kind `kind`
/// (its `kind` key aside). `None` when it reads, and for a kind that is not
/// a model's.
pub(super) fn read_error(kind: &str, text: &str, syntax: Syntax) -> Option<ReadError> {
    const HIDDEN: &[&str] = &["kind"];
    match syntax {
        Syntax::Toml => {
            let tree = match toml::de::DeTable::parse(text) {
                Ok(tree) => tree,
                Err(e) => return Some(toml_error(text, e)),
            };
            let e = toml_read(kind, &tree, HIDDEN)?;
            Some(toml_located(kind, text, &tree, HIDDEN, e))
        }
        Syntax::Json => json_read(kind, text, HIDDEN),
    }
}

/// The error `message` of the merged document of an `extends` chain, if
/// `text`, one file of the chain, raises it (its `kind`, `extends` and
/// `remove` aside). A file of a chain may leave out what its base gives,
/// so a TOML file's tables that miss a field are set aside one by one
/// until the file raises another error or reads (or [`REREAD_BUDGET`] is
/// spent).
pub(super) fn chain_error(
    kind: &str,
    text: &str,
    syntax: Syntax,
    message: &str,
) -> Option<ReadError> {
    const HIDDEN: &[&str] = &["kind", "extends", "remove"];
    let found = match syntax {
        Syntax::Toml => {
            let mut tree = toml::de::DeTable::parse(text).ok()?;
            let mut tries = 0..rereads(text);
            loop {
                tries.next()?;
                let e = toml_read(kind, &tree, HIDDEN)?;
                let span = e.span().filter(|s| !whole(text, s));
                if !e.message().starts_with("missing field") {
                    break toml_located(kind, text, &tree, HIDDEN, e);
                }
                // A missing field of the document itself: every entry
                // was read without another error.
                if !set_aside(tree.get_mut(), &span?) {
                    return None;
                }
            }
        }
        Syntax::Json => json_read(kind, text, HIDDEN)?,
    };
    (found.message == message).then_some(found)
}

/// The `kind` a model file's text declares, if it reads as a document with
/// a string `kind`.
pub(super) fn kind_of(text: &str, syntax: Syntax) -> Option<String> {
    #[derive(Deserialize)]
    struct Kind {
        kind: String,
    }
    match syntax {
        Syntax::Toml => toml::from_str::<Kind>(text).ok(),
        Syntax::Json => serde_json::from_str::<Kind>(text).ok(),
    }
    .map(|k| k.kind)
}

/// Reads the model of kind `kind` (a kind of [`super::Model`]) from `d`;
/// reads nothing for another kind.
fn read_as<'de, D: Deserializer<'de>>(kind: &str, d: D) -> Result<(), D::Error> {
    match kind {
        "pwarx" => PwarxModel::deserialize(d).map(drop),
        "hybrid_automaton" => HybridAutomaton::deserialize(d).map(drop),
        "mechanical" => MechanicalModel::deserialize(d).map(drop),
        "gray_box" => GrayBoxModel::deserialize(d).map(drop),
        _ => Ok(()),
    }
}

/// A parsed TOML document, every key and value with its span.
type Tree<'i> = Spanned<toml::de::DeTable<'i>>;

/// The error of reading `tree` as a model of kind `kind`, the top-level
/// keys `hidden` aside.
fn toml_read(kind: &str, tree: &Tree, hidden: &'static [&'static str]) -> Option<toml::de::Error> {
    let d = Hiding {
        hidden,
        inner: toml::de::Deserializer::from(tree.clone()),
    };
    read_as(kind, d).err()
}

/// True when `span` is the whole document of `text` (the parser gives the
/// root table the span `0..0`).
fn whole(text: &str, span: &Range<usize>) -> bool {
    span.start == 0 && (span.end == 0 || span.end >= text.trim_end().len())
}

/// A `toml` error: its span's line, unless the span is the whole document,
/// and the keys its display appends (`in `parameters.value``) as the entry.
fn toml_error(text: &str, mut e: toml::de::Error) -> ReadError {
    let line = e
        .span()
        .filter(|s| !whole(text, s))
        .map(|s| line_of(text, s.start));
    // Without the input, the display is the message, then the keys.
    e.set_input(None);
    let shown = e.to_string();
    let entry = shown
        .trim_end()
        .rsplit_once('\n')
        .and_then(|(_, last)| last.strip_prefix("in `")?.strip_suffix('`'))
        .map(str::to_string);
    ReadError {
        message: e.message().trim().replace('\n', " "),
        entry,
        line,
    }
}

/// [`toml_error`] of the error `e` of reading `tree` (the document of
/// `text`), with the line of the element at fault for an error placed on
/// a whole array ([`element_line`]).
fn toml_located(
    kind: &str,
    text: &str,
    tree: &Tree,
    hidden: &'static [&'static str],
    e: toml::de::Error,
) -> ReadError {
    let mut found = toml_error(text, e.clone());
    if let (Some(span), Some(entry)) = (e.span(), &found.entry)
        && let Some(line) = element_line(kind, text, tree, hidden, entry, span, e.message())
    {
        found.line = line;
    }
    found
}

/// The most bytes of text the search for the element or the file at fault
/// reads again (its tries times the size of the text): a file is read in
/// time proportional to its size, whatever its error.
const REREAD_BUDGET: usize = 64 << 20;

/// How many times `text` may be read again within [`REREAD_BUDGET`].
fn rereads(text: &str) -> usize {
    REREAD_BUDGET / text.len().max(1)
}

/// The line of the element at fault, for an error the `toml` crate places
/// on a whole array (`span`, the value of `entry` in `tree`): an element
/// serde reads from its buffer (an internally tagged enum, such as a
/// gray-box element) leaves its error without a span of its own. The
/// element is the first that raises the same `message` when the array
/// holds it alone. `None` when the error is not on an array; `Some(None)`,
/// no line rather than the first element's, when no element raises it or
/// the array is too long to try each.
fn element_line(
    kind: &str,
    text: &str,
    tree: &Tree,
    hidden: &'static [&'static str],
    entry: &str,
    span: Range<usize>,
    message: &str,
) -> Option<Option<usize>> {
    let keys: Vec<&str> = entry.split('.').collect();
    let (last, outer) = keys.split_last()?;
    // The table holding the array, reached through the tables of `outer`.
    fn holder<'a, 'i>(
        mut table: &'a mut toml::de::DeTable<'i>,
        outer: &[&str],
    ) -> Option<&'a mut toml::de::DeTable<'i>> {
        for key in outer {
            match table.get_mut(*key)?.get_mut() {
                DeValue::Table(t) => table = t,
                _ => return None,
            }
        }
        Some(table)
    }
    let mut alone = tree.clone();
    let array = holder(alone.get_mut(), outer)?.get(*last)?;
    let DeValue::Array(items) = array.get_ref() else {
        return None;
    };
    if array.span() != span {
        return None;
    }
    if items.len() > rereads(text) {
        return Some(None);
    }
    let items = items.to_vec();
    Some(items.iter().find_map(|item| {
        let mut one = toml::de::DeArray::new();
        one.push(item.clone());
        *holder(alone.get_mut(), outer)?.get_mut(*last)?.get_mut() = DeValue::Array(one);
        let e = toml_read(kind, &alone, hidden)?;
        (e.message() == message).then(|| line_of(text, item.span().start))
    }))
}

/// Removes from `table` the innermost table or array element whose span
/// is `span` (a table that misses a field); false when there is none.
fn set_aside(table: &mut toml::de::DeTable, span: &Range<usize>) -> bool {
    fn inside(value: &mut DeValue, span: &Range<usize>) -> bool {
        match value {
            DeValue::Table(t) => set_aside(t, span),
            DeValue::Array(items) => {
                if items.iter_mut().any(|item| inside(item.get_mut(), span)) {
                    return true;
                }
                let Some(at) = items.iter().position(|item| item.span() == *span) else {
                    return false;
                };
                let mut kept = toml::de::DeArray::new();
                for (i, item) in items.iter().enumerate() {
                    if i != at {
                        kept.push(item.clone());
                    }
                }
                *items = kept;
                true
            }
            _ => false,
        }
    }
    if table.iter_mut().any(|(_, v)| inside(v.get_mut(), span)) {
        return true;
    }
    let key = table
        .iter()
        .find(|(_, v)| v.span() == *span)
        .map(|(k, _)| k.clone());
    key.is_some_and(|k| table.remove(k.get_ref().as_ref()).is_some())
}

/// The error of reading the JSON `text` as a model of kind `kind`, the
/// top-level keys `hidden` aside.
fn json_read(kind: &str, text: &str, hidden: &'static [&'static str]) -> Option<ReadError> {
    let mut d = serde_json::Deserializer::from_str(text);
    let e = read_as(
        kind,
        Hiding {
            hidden,
            inner: &mut d,
        },
    )
    .err()?;
    Some(json_error(e))
}

/// A serde_json error: its line (0 means none) and its message without
/// the position serde_json appends.
fn json_error(e: serde_json::Error) -> ReadError {
    let shown = e.to_string();
    let position = format!(" at line {} column {}", e.line(), e.column());
    let message = shown.strip_suffix(&position).unwrap_or(&shown);
    ReadError {
        message: message.to_string(),
        entry: None,
        line: (e.line() > 0).then_some(e.line()),
    }
}

/// The 1-based line of byte `offset` of `text`.
fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// A deserializer of a map that hides its entries `hidden` from the
/// visitor, every other call going to `inner`, so that its errors keep
/// their position.
struct Hiding<D> {
    hidden: &'static [&'static str],
    inner: D,
}

impl<'de, D: Deserializer<'de>> Deserializer<'de> for Hiding<D> {
    type Error = D::Error;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, D::Error> {
        self.inner.deserialize_map(HidingVisitor {
            hidden: self.hidden,
            visitor,
        })
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, D::Error> {
        self.inner.deserialize_struct(
            name,
            fields,
            HidingVisitor {
                hidden: self.hidden,
                visitor,
            },
        )
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf option unit unit_struct newtype_struct seq tuple
        tuple_struct map enum identifier ignored_any
    }
}

/// The visitor of [`Hiding`]: hands the visitor a map without the hidden
/// entries.
struct HidingVisitor<V> {
    hidden: &'static [&'static str],
    visitor: V,
}

impl<'de, V: Visitor<'de>> Visitor<'de> for HidingVisitor<V> {
    type Value = V::Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        self.visitor.expecting(f)
    }

    fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<V::Value, A::Error> {
        self.visitor.visit_map(HidingMap {
            hidden: self.hidden,
            map,
        })
    }
}

/// A map without the entries whose key is one of `hidden`.
struct HidingMap<A> {
    hidden: &'static [&'static str],
    map: A,
}

impl<'de, A: MapAccess<'de>> MapAccess<'de> for HidingMap<A> {
    type Error = A::Error;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        mut seed: K,
    ) -> Result<Option<K::Value>, A::Error> {
        loop {
            let key = KeySeed {
                hidden: self.hidden,
                seed,
            };
            match self.map.next_key_seed(key)? {
                None => return Ok(None),
                Some(Key::Shown(value)) => return Ok(Some(value)),
                Some(Key::Hidden(back)) => {
                    self.map.next_value::<IgnoredAny>()?;
                    seed = back;
                }
            }
        }
    }

    fn next_value_seed<S: DeserializeSeed<'de>>(&mut self, seed: S) -> Result<S::Value, A::Error> {
        self.map.next_value_seed(seed)
    }
}

/// A key read by [`KeySeed`]: hidden (the seed, unused), or read by the
/// seed.
enum Key<K, T> {
    Hidden(K),
    Shown(T),
}

/// Reads a key as text; a hidden one is handed back with the seed, any
/// other is read by the seed (inside the parser's key, so that an error
/// gets the key's position).
struct KeySeed<K> {
    hidden: &'static [&'static str],
    seed: K,
}

impl<'de, K: DeserializeSeed<'de>> DeserializeSeed<'de> for KeySeed<K> {
    type Value = Key<K, K::Value>;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_str(self)
    }
}

impl<'de, K: DeserializeSeed<'de>> Visitor<'de> for KeySeed<K> {
    type Value = Key<K, K::Value>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a key")
    }

    fn visit_str<E: de::Error>(self, key: &str) -> Result<Self::Value, E> {
        if self.hidden.contains(&key) {
            return Ok(Key::Hidden(self.seed));
        }
        let d = de::value::StrDeserializer::<E>::new(key);
        self.seed.deserialize(d).map(Key::Shown)
    }

    fn visit_borrowed_str<E: de::Error>(self, key: &'de str) -> Result<Self::Value, E> {
        if self.hidden.contains(&key) {
            return Ok(Key::Hidden(self.seed));
        }
        let d = de::value::BorrowedStrDeserializer::<E>::new(key);
        self.seed.deserialize(d).map(Key::Shown)
    }

    fn visit_string<E: de::Error>(self, key: String) -> Result<Self::Value, E> {
        if self.hidden.iter().any(|h| *h == key) {
            return Ok(Key::Hidden(self.seed));
        }
        let d = de::value::StringDeserializer::<E>::new(key);
        self.seed.deserialize(d).map(Key::Shown)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rust's and serde's words become a model author's; a message
    /// without them is kept.
    #[test]
    fn messages_name_numbers_lists_and_tables() {
        let e = |message: &str, entry: Option<&str>| ReadError {
            message: message.into(),
            entry: entry.map(str::to_string),
            line: None,
        };
        assert_eq!(
            e(
                "invalid type: string \"25.0\", expected f64",
                Some("parameters.value")
            )
            .describe(),
            "parameters.value: invalid type: string \"25.0\", expected a number"
        );
        assert_eq!(
            e("invalid value: integer `-1`, expected u32", Some("format")).describe(),
            "format: invalid value: integer `-1`, expected a whole number >= 0"
        );
        assert_eq!(
            e("invalid type: map, expected a sequence", None).describe(),
            "invalid type: table, expected a list"
        );
        assert_eq!(
            e("missing field `value`", None).describe(),
            "missing field `value`"
        );
    }

    #[test]
    fn the_tag_is_hidden_and_everything_else_read() {
        let toml = "kind = \"pwarx\"\nna = 1\nnb = 0\ninputs = 0\n[[modes]]\ntheta = [0.5, 0.0]\n";
        assert_eq!(read_error("pwarx", toml, Syntax::Toml), None);
        let json =
            r#"{"na": 1, "kind": "pwarx", "nb": 0, "inputs": 0, "modes": [{"theta": [0.5, 0.0]}]}"#;
        assert_eq!(read_error("pwarx", json, Syntax::Json), None);
        // Not hidden, the tag is an unknown field of the struct.
        let tree = toml::de::DeTable::parse(toml).unwrap();
        let e = toml_read("pwarx", &tree, &[]).unwrap();
        assert!(e.message().starts_with("unknown field `kind`"), "{e:?}");
        assert_eq!(toml_error(toml, e).line, Some(1));
    }

    #[test]
    fn errors_keep_their_line_and_entry() {
        let toml = "kind = \"pwarx\"\nna = 1\nnb = 0\ninputs = 0\n\n[[modes]]\ntheta = [0.5, 0.0]\n\
                    regoin = { a = [[1.0]], b = [0.0] }\n";
        let e = read_error("pwarx", toml, Syntax::Toml).unwrap();
        assert_eq!(e.line, Some(8), "{e:?}");
        assert_eq!(e.entry.as_deref(), Some("modes"), "{e:?}");
        assert!(e.message.starts_with("unknown field `regoin`"), "{e:?}");
        assert_eq!(
            e.describe(),
            format!("modes: {}", e.message),
            "the entry comes first"
        );

        let typed = toml
            .replace("na = 1", "na = \"one\"")
            .replace("regoin", "region");
        let e = read_error("pwarx", &typed, Syntax::Toml).unwrap();
        assert_eq!((e.line, e.entry.as_deref()), (Some(2), Some("na")), "{e:?}");

        let json = "{\n  \"kind\": \"pwarx\",\n  \"na\": 1, \"nb\": 0, \"inputs\": 0,\n  \"modes\": [\n    \
                    {\"theta\": [0.5, \"x\"]}\n  ]\n}\n";
        let e = read_error("pwarx", json, Syntax::Json).unwrap();
        assert_eq!(e.line, Some(5), "{e:?}");
        assert_eq!(e.message, "invalid type: string \"x\", expected f64");

        // A missing top-level field: the whole document, no line.
        let e = read_error("pwarx", "kind = \"pwarx\"\nna = 1\n", Syntax::Toml).unwrap();
        assert_eq!(e.line, None, "{e:?}");
        assert!(e.message.starts_with("missing field"), "{e:?}");
    }
}
