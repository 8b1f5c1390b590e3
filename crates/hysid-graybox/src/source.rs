//! Where a piece of text is written in a model file's source (TOML or
//! JSON), for the line of an error ([`crate::InvalidGrayBox::line_in`]).
//!
//! The source is split into its strings and the rest of each line, its
//! comments left out: a name counts where it is a whole string or a key,
//! never inside a comment or as part of another word.

/// A model file's source, read for where things are written.
struct Lexed {
    /// Every string: the line it starts on (from 0) and its text as
    /// written (escapes not read), in source order.
    strings: Vec<(usize, String)>,
    /// Per line, the text outside strings and comments, each string
    /// replaced by a space.
    code: Vec<String>,
}

impl Lexed {
    /// Splits `source` into strings, comments and the rest. TOML's four
    /// kinds of string (`"..."`, `'...'`, `"""..."""`, `'''...'''`) and `#`
    /// comments; JSON's strings are TOML's basic strings, and a JSON file
    /// has no `#` or `'` outside them.
    fn of(source: &str) -> Self {
        let mut strings = Vec::new();
        let mut code = vec![String::new()];
        let mut line = 0;
        let mut rest = source;
        while let Some(c) = rest.chars().next() {
            match c {
                '"' | '\'' => {
                    let triple = if c == '"' { "\"\"\"" } else { "'''" };
                    let (open, close) = if rest.starts_with(triple) {
                        (3, triple)
                    } else {
                        (1, if c == '"' { "\"" } else { "'" })
                    };
                    let body = &rest[open..];
                    let escapes = c == '"';
                    let end = string_end(body, close, escapes, open == 1);
                    let text = &body[..end];
                    strings.push((line, text.to_string()));
                    for _ in text.matches('\n') {
                        line += 1;
                        code.push(String::new());
                    }
                    code[line].push(' ');
                    rest = &body[(end + close.len()).min(body.len())..];
                }
                '#' => {
                    let end = rest.find('\n').unwrap_or(rest.len());
                    rest = &rest[end..];
                }
                '\n' => {
                    line += 1;
                    code.push(String::new());
                    rest = &rest[1..];
                }
                _ => {
                    code[line].push(c);
                    rest = &rest[c.len_utf8()..];
                }
            }
        }
        Lexed { strings, code }
    }
}

/// The length of the body of a string that `close` ends: up to the first
/// `close` not escaped by a backslash (with `escapes`), or the end of the
/// line for a one-line string left open, or of the source.
fn string_end(body: &str, close: &str, escapes: bool, one_line: bool) -> usize {
    let bytes = body.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        if escapes && bytes[i] == b'\\' {
            i += 2;
            continue;
        }
        if one_line && bytes[i] == b'\n' {
            return i;
        }
        // Bytes, not characters: `close` and the newline are ASCII, which
        // no byte inside a longer character equals, so a match is always
        // at a character's start.
        if bytes[i..].starts_with(close.as_bytes()) {
            return i;
        }
        i += 1;
    }
    body.len()
}

/// True for text that may be a bare TOML key (`A-Za-z0-9_-`).
fn is_bare_key(text: &str) -> bool {
    !text.is_empty()
        && text
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// True when `code` (a line outside strings and comments) writes `key` as
/// a key: a whole word followed by `=` (`key = ...`, `{ key = ...`,
/// `table.key = ...`).
fn writes_key(code: &str, key: &str) -> bool {
    let word = |b: u8| b.is_ascii_alphanumeric() || b == b'_' || b == b'-';
    code.match_indices(key).any(|(at, _)| {
        let before = code[..at].bytes().next_back();
        let after = &code[at + key.len()..];
        !before.is_some_and(word)
            && !after.bytes().next().is_some_and(word)
            && after.trim_start().starts_with('=')
    })
}

/// The 1-based line of `source` where `text` is written: the first line
/// holding it as a whole string, or as a key when it is a name; else, for
/// text that is not a name (an expression), the first line of a string
/// that holds it (a string over several lines, or with escapes). Comments
/// and words that merely contain it do not count.
pub(crate) fn line_of(source: &str, text: &str) -> Option<usize> {
    first_line(&Lexed::of(source), text)
}

/// [`line_of`] in a lexed source.
fn first_line(lexed: &Lexed, text: &str) -> Option<usize> {
    let as_string = lexed
        .strings
        .iter()
        .find(|(_, s)| s == text)
        .map(|&(line, _)| line);
    let as_key = is_bare_key(text)
        .then(|| lexed.code.iter().position(|code| writes_key(code, text)))
        .flatten();
    let line = match (as_string, as_key) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    let line = line.or_else(|| {
        if is_bare_key(text) {
            return None;
        }
        lexed.strings.iter().find_map(|(line, s)| {
            let at = s.find(text)?;
            Some(line + s[..at].matches('\n').count())
        })
    });
    line.map(|l| l + 1)
}

/// [`line_of`], preferring a line where `key` writes `text` as a whole
/// string (`guard = "p"` before `states = ["p"]` for the guard's `p`),
/// then one where `key` and `text` are both written as keys.
pub(crate) fn line_of_field(source: &str, key: &str, text: &str) -> Option<usize> {
    let lexed = Lexed::of(source);
    let in_field = (lexed.strings.iter())
        .find(|(line, s)| s == text && writes_key(&lexed.code[*line], key))
        .map(|&(line, _)| line + 1);
    // A name as a key of the field's table on its line
    // (`estimate = { x = [0, 1] }` for the estimate of `x`).
    let keyed = || {
        is_bare_key(text)
            .then(|| {
                (lexed.code.iter()).position(|code| writes_key(code, key) && writes_key(code, text))
            })
            .flatten()
            .map(|line| line + 1)
    };
    in_field.or_else(keyed).or_else(|| first_line(&lexed, text))
}

impl Lexed {
    /// Whether line `line` writes `key` as a key: TOML's `key =`, or a
    /// JSON line whose first string is `key` followed by `:`.
    fn keys(&self, line: usize, key: &str) -> bool {
        let code = &self.code[line];
        let json = || {
            let first = self.strings.iter().find(|(l, _)| *l == line);
            first.is_some_and(|(_, s)| s == key) && code.trim_start().starts_with(':')
        };
        writes_key(code, key) || json()
    }

    /// Whether line `line` ends an entry of a list of tables: a TOML
    /// table header, or a line that opens a JSON object.
    fn opens_entry(&self, line: usize) -> bool {
        let code = self.code[line].trim_start();
        code.starts_with('[') || code.starts_with('{')
    }
}

/// The 1-based line of the `nth` (from 0) entry of `source` whose `name`
/// key writes `name` (`name = "free"` of a `[[modes]]` table or an inline
/// table, `"name": "free"` of a JSON object): that line, or with `key` the
/// line of the entry that writes `key` (after the name, up to the next
/// entry, else before it, back to the entry's start), the name's line
/// when the entry writes no such key. `None` when no such entry is
/// written.
pub(crate) fn entry_line(source: &str, name: &str, key: Option<&str>, nth: usize) -> Option<usize> {
    let lexed = Lexed::of(source);
    let at = (lexed.strings.iter())
        .filter(|(line, s)| s == name && lexed.keys(*line, "name"))
        .map(|&(line, _)| line)
        .nth(nth)?;
    let Some(key) = key else {
        return Some(at + 1);
    };
    let lines = lexed.code.len();
    let after = (at..lines)
        .take_while(|&l| l == at || !(lexed.opens_entry(l) || lexed.keys(l, "name")))
        .find(|&l| lexed.keys(l, key));
    let before = || {
        (0..at)
            .rev()
            .take_while(|&l| !lexed.keys(l, "name"))
            .take_while(|&l| l + 1 == at || !lexed.opens_entry(l + 1))
            .find(|&l| lexed.keys(l, key))
    };
    Some(after.or_else(before).unwrap_or(at) + 1)
}

/// The 1-based line of `source` that first writes `key` as a key (TOML or
/// JSON): where a definition is written, not where it is read.
pub(crate) fn key_line(source: &str, key: &str) -> Option<usize> {
    let lexed = Lexed::of(source);
    (0..lexed.code.len())
        .find(|&l| lexed.keys(l, key))
        .map(|l| l + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_is_found_where_it_is_a_string_or_a_key() {
        let toml = "# w is the angular speed\n\
                    states = [\"x\"]  # no w here either\n\
                    name = \"wheel, w\"\n\
                    initial_state = { from = \"given\", estimate = { w = [0, 1] } }\n";
        assert_eq!(line_of(toml, "w"), Some(4));
        assert_eq!(line_of(toml, "x"), Some(2));
        assert_eq!(line_of(toml, "estimate"), Some(4));
        // Only in a comment, or inside another word or string.
        assert_eq!(line_of(toml, "angular"), None);
        assert_eq!(line_of(toml, "whe"), None);
        assert_eq!(line_of(toml, "wheel"), None);
        // Dotted keys, quoted keys and JSON keys.
        assert_eq!(line_of("a = 1\nestimate.w = [0, 1]\n", "w"), Some(2));
        assert_eq!(line_of("a = 1\n\"w\" = [0, 1]\n", "w"), Some(2));
        assert_eq!(
            line_of("{\n  \"estimate\": {\"w\": [0, 1]}\n}\n", "w"),
            Some(2)
        );
    }

    /// Characters of several bytes in strings, escaped or not, and in
    /// comments: the lines are found and nothing is cut inside one.
    #[test]
    fn strings_of_any_characters_are_read() {
        let toml = concat!(
            "unit = \"°C\" # für µ\n",
            "doc = \"Ω \\µ \\\"q\\\" '\"\n",
            "name = \"tau\"\n",
            "note = '''Raum\n20 °C'''\n",
            "value = \"q\"\n",
        );
        assert_eq!(line_of(toml, "tau"), Some(3));
        assert_eq!(line_of(toml, "°C"), Some(1));
        assert_eq!(line_of(toml, "q"), Some(6));
        assert_eq!(line_of(toml, "20 °C"), Some(5));
    }

    #[test]
    fn an_entry_is_found_by_its_name() {
        let toml = concat!(
            "initial_state = { from = \"given\", mode = \"free\" }\n",
            "[[modes]]\n",
            "name = \"free\"\n",
            "invariant = [\"x <= 1\"]\n",
            "flow = { x = \"v\" }\n",
            "[[modes]]\n",
            "name = \"wall\"\n",
            "[[modes]]\n",
            "name = \"free\"\n",
            "flow = { x = \"0\" }\n",
        );
        assert_eq!(entry_line(toml, "free", None, 0), Some(3));
        assert_eq!(entry_line(toml, "free", Some("flow"), 0), Some(5));
        assert_eq!(entry_line(toml, "free", Some("flow"), 1), Some(10));
        assert_eq!(entry_line(toml, "free", None, 1), Some(9));
        // The key is looked for in the entry only; an entry without it
        // gives its name's line.
        assert_eq!(entry_line(toml, "wall", Some("flow"), 0), Some(7));
        assert_eq!(entry_line(toml, "none", None, 0), None);
        // The key written before the name.
        let first = "[[modes]]\nflow = { x = \"v\" }\nname = \"free\"\n[[modes]]\nflow = {}\nname = \"wall\"\n";
        assert_eq!(entry_line(first, "free", Some("flow"), 0), Some(2));
        assert_eq!(entry_line(first, "wall", Some("flow"), 0), Some(5));
        // JSON, one key to a line.
        let json = concat!(
            "{\n",
            "  \"initial_state\": {\"from\": \"given\", \"mode\": \"free\"},\n",
            "  \"modes\": [\n",
            "    {\n",
            "      \"name\": \"free\",\n",
            "      \"flow\": {\"x\": \"v\"}\n",
            "    },\n",
            "    {\n",
            "      \"flow\": {\"x\": \"0\"},\n",
            "      \"name\": \"free\"\n",
            "    }\n",
            "  ],\n",
            "  \"definitions\": {\"reach\": \"ra\", \"ra\": \"rb\"}\n",
            "}\n",
        );
        assert_eq!(entry_line(json, "free", None, 0), Some(5));
        assert_eq!(entry_line(json, "free", Some("flow"), 0), Some(6));
        assert_eq!(entry_line(json, "free", None, 1), Some(10));
        assert_eq!(entry_line(json, "free", Some("flow"), 1), Some(9));
        // A definition's key, not a string that reads it.
        let toml = "[definitions]\nreach = \"ra\"\nra = \"2*rb\"\n";
        assert_eq!(key_line(toml, "ra"), Some(3));
        assert_eq!(line_of(toml, "ra"), Some(2));
    }

    #[test]
    fn a_name_is_found_where_its_field_writes_it() {
        let toml = "states = [\"w\", \"p\"]\n\
                    [[transitions]]\n\
                    guard = \"p\"\n";
        assert_eq!(line_of(toml, "p"), Some(1));
        assert_eq!(line_of_field(toml, "guard", "p"), Some(3));
        // No such field: the first line that writes it.
        assert_eq!(line_of_field(toml, "when", "p"), Some(1));
        // A name that is a key of the field's table on the field's line.
        let toml = "states = [\"x\"]\n\
                    # estimate = { x = [0, 1] }\n\
                    initial_state = { from = \"given\", estimate = { x = [2, 1] } }\n";
        assert_eq!(line_of_field(toml, "estimate", "x"), Some(3));
        assert_eq!(line_of_field(toml, "values", "x"), Some(1));
    }

    #[test]
    fn an_expression_is_found_in_its_string() {
        let toml = "# F = \"ku*u - c1*y\" before\n\
                    energy = '0.5*v^2'\n\
                    [definitions]\n\
                    F = \"ku*u - c1*y\"\n\
                    G = \"\"\"\n2*F + ku*u - c1*y\n\"\"\"\n\
                    H = \"a \\\" # b\"\n\
                    K = \"y\"\n";
        assert_eq!(line_of(toml, "ku*u - c1*y"), Some(4));
        assert_eq!(line_of(toml, "0.5*v^2"), Some(2));
        assert_eq!(line_of(toml, "2*F"), Some(6));
        // A `#` inside a string opens no comment.
        assert_eq!(line_of(toml, "y"), Some(9));
    }
}
