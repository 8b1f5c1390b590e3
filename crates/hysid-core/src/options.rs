//! Typed back-end options, mirrored 1:1 by `--set key=value`.
//!
//! A back-end declares its options once with [`backend_options!`](crate::backend_options): the macro
//! writes the struct (with `Default` holding the documented defaults), and
//! the [`OptionSpec`] list that `hysid methods` prints. `--set` values are
//! parsed as TOML scalars (`3`, `0.5`, `true`) or else taken as text, then
//! deserialised into the struct, so a typo or a wrong type is an error
//! naming the option.

use serde::Serialize;
use serde::de::DeserializeOwned;
use std::collections::BTreeMap;

/// Description of one option, for `hysid methods` and docs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OptionSpec {
    /// Key used with `--set`.
    pub key: &'static str,
    /// Type as shown to users (`int`, `float`, `bool`, `fv|lpv`, ...).
    pub ty: String,
    /// Default value, as text.
    pub default: String,
    /// One-paragraph documentation.
    pub doc: String,
}

/// Implemented by the options struct of every back-end (by [`backend_options!`](crate::backend_options)).
pub trait BackendOptions: Default + Serialize + DeserializeOwned + Clone + Send + Sync {
    /// The options' descriptions, in declaration order.
    fn specs() -> Vec<OptionSpec>;

    /// The options as a JSON map (recorded in model files).
    fn to_map(&self) -> BTreeMap<String, serde_json::Value> {
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(m)) => m.into_iter().collect(),
            _ => BTreeMap::new(),
        }
    }
}

/// How an option's type is shown; implemented for the scalar types used in
/// options and by enums with [`option_enum!`](crate::option_enum).
pub trait OptionType {
    /// Name shown in `hysid methods`.
    fn type_name() -> String;
}

macro_rules! scalar_option_type {
    ($($t:ty => $n:literal),*) => { $(impl OptionType for $t { fn type_name() -> String { $n.into() } })* };
}
scalar_option_type!(usize => "int", u64 => "int", u32 => "int", i64 => "int", f64 => "float", bool => "bool", String => "text");

impl<T: OptionType> OptionType for Option<T> {
    fn type_name() -> String {
        format!("{} (optional)", T::type_name())
    }
}

/// The key of the preset every back-end accepts (`--set preset=paper`):
/// `default`, the back-end's documented defaults, or `paper`, the
/// procedure of the back-end's paper exactly
/// ([`Identifier::PAPER`](crate::backend::Identifier::PAPER)). Options
/// given beside it override it.
pub const PRESET: &str = "preset";

/// The description of [`PRESET`] for a back-end whose paper's procedure
/// is its defaults with `paper` set.
pub fn preset_spec(paper: &[(&str, &str)]) -> OptionSpec {
    let differs = if paper.is_empty() {
        "the same as the defaults".to_string()
    } else {
        let pairs: Vec<String> = paper.iter().map(|(k, v)| format!("{k}={v}")).collect();
        format!("the defaults with {}", pairs.join(", "))
    };
    OptionSpec {
        key: PRESET,
        ty: "default|paper".to_string(),
        default: "default".to_string(),
        doc: format!(
            "default: the defaults above; paper: the procedure as its paper publishes it \
             ({differs}). Options given beside it override it."
        ),
    }
}

/// Text of a default value: TOML scalar syntax, `none` for `None`.
pub fn show_default<T: Serialize>(v: &T) -> String {
    match serde_json::to_value(v) {
        Ok(serde_json::Value::String(s)) => s,
        Ok(serde_json::Value::Null) => "none".into(),
        Ok(x) => x.to_string(),
        Err(_) => String::new(),
    }
}

/// `key=value` pairs from the command line (or an experiment file).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Settings {
    pairs: Vec<(String, String)>,
}

/// Errors in back-end options, from `--set` on the command line or a run's
/// settings in an experiment file. The text says "option"; the CLI words it
/// as `--set` ([`OptionError::render`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OptionError {
    /// Not of the form key=value.
    #[error("{}", self.render("option"))]
    Syntax(String),
    /// Key given twice.
    #[error("{}", self.render("option"))]
    Duplicate(String),
    /// Unknown key.
    #[error("{}", self.render("option"))]
    Unknown {
        /// Key.
        key: String,
        /// Back-end.
        method: String,
        /// Known keys.
        known: String,
    },
    /// A value that does not parse as the option's type.
    #[error("{}", self.render("option"))]
    Value {
        /// Key.
        key: String,
        /// Value as given.
        value: String,
        /// Back-end.
        method: String,
        /// Expected type.
        ty: String,
        /// Parser message.
        message: String,
    },
    /// A required option that was not given.
    #[error("{}", self.render("option"))]
    Missing {
        /// Key.
        key: &'static str,
        /// Back-end.
        method: &'static str,
        /// What the option is ("an error bound").
        what: &'static str,
        /// The forms a value takes, as shown to users (`<bound in output
        /// units>`, `auto`).
        forms: &'static [&'static str],
    },
    /// A value of the right type outside the option's valid range, found by
    /// the back-end's [`CheckOptions::check`].
    #[error("{}", self.render("option"))]
    Invalid {
        /// Key.
        key: &'static str,
        /// Value, as the option shows it.
        value: String,
        /// What a valid value is ("must be a finite number >= 0").
        requirement: String,
    },
}

impl OptionError {
    /// An out-of-range `value` of option `key`.
    pub fn invalid(
        key: &'static str,
        value: impl ToString,
        requirement: impl Into<String>,
    ) -> Self {
        Self::Invalid {
            key,
            value: value.to_string(),
            requirement: requirement.into(),
        }
    }

    /// The option the error is about, where it names one.
    pub fn key(&self) -> Option<&str> {
        match self {
            Self::Syntax(_) => None,
            Self::Duplicate(key) | Self::Unknown { key, .. } | Self::Value { key, .. } => Some(key),
            Self::Missing { key, .. } | Self::Invalid { key, .. } => Some(key),
        }
    }

    /// The message with `prefix` naming where options come from: `option`
    /// in libraries, `--set` on the command line.
    pub fn render(&self, prefix: &str) -> String {
        match self {
            Self::Syntax(item) => format!("{prefix} '{item}': expected key=value"),
            Self::Duplicate(key) => format!("{prefix} {key}: given twice"),
            Self::Unknown { key, method, known } => {
                format!("{prefix} {key}: method '{method}' has no such option (options: {known})")
            }
            Self::Value {
                key,
                value,
                method,
                ty,
                message,
            } => format!("{prefix} {key}={value}: {message} (method '{method}', expected {ty})"),
            Self::Missing {
                key,
                method,
                what,
                forms,
            } => {
                let given: Vec<String> = forms
                    .iter()
                    .map(|f| format!("{prefix} {key}={f}"))
                    .collect();
                format!("method '{method}' needs {what}: {}", given.join(" or "))
            }
            Self::Invalid {
                key,
                value,
                requirement,
            } => format!("{prefix} {key}={value}: {requirement}"),
        }
    }
}

/// The checks of a back-end's options beyond their types: ranges, and
/// combinations that cannot work. Run once, by [`Checked::new`], before
/// any data is touched (the shape of linfa's `ParamGuard`).
pub trait CheckOptions {
    /// `Ok` when every option is valid, else the first invalid one.
    fn check(&self) -> Result<(), OptionError>;
}

/// Options that passed [`CheckOptions::check`]: what a back-end's `fit`
/// receives, so that no step re-checks them.
#[derive(Debug, Clone, PartialEq)]
pub struct Checked<T>(T);

impl<T: CheckOptions> Checked<T> {
    /// Checks `options`.
    pub fn new(options: T) -> Result<Self, OptionError> {
        options.check()?;
        Ok(Self(options))
    }

    /// The options, checked.
    pub fn into_inner(self) -> T {
        self.0
    }
}

impl<T> std::ops::Deref for Checked<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

/// The largest count a count option (restarts, particles, starts) takes:
/// each of them is held in memory or drawn up front.
pub const MAX_COUNT: usize = 100_000;

/// Checks that a count option lies in `least..=MAX_COUNT`.
pub fn check_count(key: &'static str, value: usize, least: usize) -> Result<(), OptionError> {
    if (least..=MAX_COUNT).contains(&value) {
        Ok(())
    } else {
        Err(OptionError::invalid(
            key,
            value,
            format!("must be in {least}..={MAX_COUNT}"),
        ))
    }
}

/// Checks that a float option is finite and satisfies `ok`.
pub fn check_float(
    key: &'static str,
    value: f64,
    ok: impl Fn(f64) -> bool,
    requirement: &str,
) -> Result<(), OptionError> {
    if value.is_finite() && ok(value) {
        Ok(())
    } else {
        Err(OptionError::invalid(key, short(value), requirement))
    }
}

/// `value` as written (`-1`, `0.25`), or with an exponent (`1e308`) where
/// that would take more than 16 characters.
pub(crate) fn short(value: f64) -> String {
    let plain = value.to_string();
    if plain.len() > 16 {
        format!("{value:e}")
    } else {
        plain
    }
}

impl Settings {
    /// Parses `key=value` strings.
    pub fn parse<S: AsRef<str>>(items: &[S]) -> Result<Self, OptionError> {
        let mut pairs: Vec<(String, String)> = Vec::new();
        for it in items {
            let it = it.as_ref();
            let (k, v) = it
                .split_once('=')
                .ok_or_else(|| OptionError::Syntax(it.to_string()))?;
            let k = k.trim().to_string();
            if k.is_empty() {
                return Err(OptionError::Syntax(it.to_string()));
            }
            if pairs.iter().any(|(p, _)| *p == k) {
                return Err(OptionError::Duplicate(k));
            }
            pairs.push((k, v.trim().to_string()));
        }
        Ok(Self { pairs })
    }

    /// From pairs already split.
    pub fn from_pairs(pairs: Vec<(String, String)>) -> Self {
        Self { pairs }
    }

    /// The pairs.
    pub fn pairs(&self) -> &[(String, String)] {
        &self.pairs
    }

    /// Value given for `key`, if any.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.pairs
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// A copy without `key`.
    pub fn without(&self, key: &str) -> Self {
        Self {
            pairs: self
                .pairs
                .iter()
                .filter(|(k, _)| k != key)
                .cloned()
                .collect(),
        }
    }

    /// A copy with `key` set to `value` (replacing its value, if given).
    pub fn with(&self, key: &str, value: &str) -> Self {
        let mut pairs = self.without(key).pairs;
        pairs.push((key.to_string(), value.to_string()));
        Self { pairs }
    }

    /// The settings with the preset ([`PRESET`]) written out: with
    /// `preset=paper`, the pairs of `paper` whose keys are not given, then
    /// the given pairs; without a preset or with `preset=default`, the
    /// given pairs. The preset's own key is not kept.
    pub fn with_preset(&self, paper: &[(&str, &str)]) -> Result<Self, OptionError> {
        let given = self.without(PRESET);
        match self.get(PRESET) {
            None | Some("default") => Ok(given),
            Some("paper") => {
                let mut pairs: Vec<(String, String)> = paper
                    .iter()
                    .filter(|(k, _)| given.get(k).is_none())
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .collect();
                pairs.extend(given.pairs);
                Ok(Self { pairs })
            }
            Some(other) => Err(OptionError::invalid(
                PRESET,
                other,
                "must be default or paper",
            )),
        }
    }

    /// Builds typed options: defaults, overridden by the given keys.
    pub fn resolve<T: BackendOptions>(&self, method: &str) -> Result<T, OptionError> {
        let specs = T::specs();
        let mut table = toml::Table::new();
        let mut unset = Vec::new();
        for (k, v) in &self.pairs {
            let Some(spec) = specs.iter().find(|s| s.key == k) else {
                return Err(OptionError::Unknown {
                    key: k.clone(),
                    method: method.to_string(),
                    known: specs.iter().map(|s| s.key).collect::<Vec<_>>().join(", "),
                });
            };
            // `none`, the text of an optional option's absent value.
            if v == "none" && spec.ty.ends_with("(optional)") {
                unset.push(k.clone());
            } else {
                let value = scalar(v).map_err(|kind| OptionError::Value {
                    key: k.clone(),
                    value: v.clone(),
                    method: method.to_string(),
                    ty: spec.ty.clone(),
                    message: format!("{kind}, where the option takes one value"),
                })?;
                table.insert(k.clone(), value);
            }
        }
        // Start from the defaults so that partial settings work.
        let mut base = match toml::Table::try_from(T::default()) {
            Ok(t) => t,
            Err(_) => toml::Table::new(),
        };
        for k in &unset {
            base.remove(k);
        }
        for (k, v) in table {
            base.insert(k, v);
        }
        T::deserialize(toml::Value::Table(base)).map_err(|e| {
            let msg = e.to_string().trim().replace('\n', " ");
            // Attribute the failure to the first given key the message names,
            // else to the first given key.
            let (key, value) = self
                .pairs
                .iter()
                .find(|(k, _)| msg.contains(k.as_str()))
                .or(self.pairs.first())
                .cloned()
                .unwrap_or_default();
            let ty = specs
                .iter()
                .find(|s| s.key == key)
                .map(|s| s.ty.clone())
                .unwrap_or_default();
            OptionError::Value {
                key,
                value,
                method: method.to_string(),
                ty,
                message: msg,
            }
        })
    }
}

/// The value of an option as text (`--set`, or an experiment's `set`
/// table written out): a TOML number, boolean or string, else the text as
/// a string; a TOML list or table (which no option takes) is refused,
/// named as such.
fn scalar(v: &str) -> Result<toml::Value, &'static str> {
    match format!("v = {v}").parse::<toml::Table>() {
        Ok(mut t) => match t.remove("v") {
            Some(toml::Value::Array(_)) => Err("a list"),
            Some(toml::Value::Table(_)) => Err("a table"),
            Some(toml::Value::Datetime(_)) | None => Ok(toml::Value::String(v.to_string())),
            Some(x) => Ok(x),
        },
        // A number TOML does not write (`1e400`, `.5`) is still a number: a
        // float option's own check then says what it needs.
        Err(_) => Ok(match v.trim().parse::<f64>() {
            Ok(x) => toml::Value::Float(x),
            Err(_) => toml::Value::String(v.to_string()),
        }),
    }
}

/// Declares a back-end's options struct: fields with documented defaults.
/// A field may carry `#[serde(...)]` attributes after its doc comment, e.g.
/// `skip_serializing_if` for an option that is recorded in model files only
/// when it differs from its default.
///
/// ```
/// hysid_core::backend_options! {
///     /// Options of an example back-end.
///     pub struct ExampleOptions {
///         /// Ridge added to the normal equations.
///         ridge: f64 = 0.0,
///         /// Number of restarts.
///         restarts: usize = 15,
///     }
/// }
/// use hysid_core::options::BackendOptions;
/// assert_eq!(ExampleOptions::default().restarts, 15);
/// assert_eq!(ExampleOptions::specs()[1].default, "15");
/// ```
#[macro_export]
macro_rules! backend_options {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[doc = $doc:literal])* $(#[serde($($serde:tt)*)])* $field:ident : $ty:ty = $default:expr ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(default, deny_unknown_fields)]
        $vis struct $name {
            $( $(#[doc = $doc])* #[doc = concat!("\n\nDefault: `", stringify!($default), "`.")] $(#[serde($($serde)*)])* pub $field: $ty, )*
        }
        impl Default for $name {
            fn default() -> Self { Self { $( $field: $default, )* } }
        }
        impl $crate::options::BackendOptions for $name {
            fn specs() -> Vec<$crate::options::OptionSpec> {
                let d = Self::default();
                vec![ $( $crate::options::OptionSpec {
                    key: stringify!($field),
                    ty: <$ty as $crate::options::OptionType>::type_name(),
                    default: $crate::options::show_default(&d.$field),
                    doc: [$($doc),*].iter().map(|l: &&str| l.trim()).collect::<Vec<_>>().join(" ").trim().to_string(),
                }, )* ]
            }
        }
    };
}

/// Declares a unit-variant enum usable as an option value (`fv|lpv`),
/// serialised in lower case.
#[macro_export]
macro_rules! option_enum {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident { $( $(#[doc = $doc:literal])* $variant:ident => $text:literal ),+ $(,)? }
    ) => {
        $(#[$meta])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
        $vis enum $name { $( $(#[doc = $doc])* #[serde(rename = $text)] $variant, )+ }
        impl $crate::options::OptionType for $name {
            fn type_name() -> String { [$($text),+].join("|") }
        }
    };
}

/// A list read from a file that is not empty; an empty one is refused
/// with `remedy` (`seeds = []`: "give the seeds, or leave seeds out").
pub fn non_empty<'de, D, T>(d: D, remedy: &str) -> Result<Vec<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::Deserialize<'de>,
{
    let items = <Vec<T> as serde::Deserialize>::deserialize(d)?;
    if items.is_empty() {
        return Err(serde::de::Error::custom(format!("an empty list: {remedy}")));
    }
    Ok(items)
}

/// The first item of `items` that an earlier one repeats (a grid's value,
/// a run's seed, a name in a prior's list): each is one choice, listed
/// once.
pub fn first_repeated<T: PartialEq>(items: &[T]) -> Option<&T> {
    (items.iter().enumerate())
        .find(|(i, x)| items[..*i].contains(x))
        .map(|(_, x)| x)
}

#[cfg(test)]
mod tests {
    use super::*;

    option_enum! {
        /// Feature kinds.
        pub enum Features { /// both
            Fv => "fv", /// theta only
            Lpv => "lpv" }
    }

    backend_options! {
        /// Test options.
        pub struct T {
            /// Size of local datasets.
            c: usize = 20,
            /// Ridge.
            ridge: f64 = 1e-3,
            /// Features.
            features: Features = Features::Fv,
            /// Optional bound.
            delta: Option<f64> = None,
        }
    }

    #[test]
    fn defaults_types_and_docs() {
        let s = T::specs();
        assert_eq!(s.len(), 4);
        assert_eq!(
            (s[0].key, s[0].ty.as_str(), s[0].default.as_str()),
            ("c", "int", "20")
        );
        assert_eq!(s[2].ty, "fv|lpv");
        assert_eq!(s[2].default, "fv");
        assert_eq!(s[3].default, "none");
        assert_eq!(s[0].doc, "Size of local datasets.");
    }

    /// `none` unsets an optional option (the text its default shows), and
    /// is refused for the others.
    #[test]
    fn none_unsets_an_optional_option_only() {
        let t: T = Settings::parse(&["delta=none"])
            .unwrap()
            .resolve("m")
            .unwrap();
        assert_eq!(t, T::default());
        let e = Settings::parse(&["c=none"])
            .unwrap()
            .resolve::<T>("m")
            .unwrap_err()
            .to_string();
        assert!(e.contains("c=none"), "{e}");
    }

    /// A list or a table, which no option takes, is named as such (it was
    /// read as the string of its text).
    #[test]
    fn a_list_or_a_table_is_named_as_such() {
        for (given, kind) in [("ridge=[0.1]", "a list"), ("features={ a = 1 }", "a table")] {
            let e = Settings::parse(&[given])
                .unwrap()
                .resolve::<T>("m")
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!(
                    "{given}: {kind}, where the option takes one value"
                )),
                "{e}"
            );
        }
    }

    #[test]
    fn set_overrides_and_errors_name_the_key() {
        let t: T = Settings::parse(&["c=40", "features=lpv", "ridge=0", "delta=0.1"])
            .unwrap()
            .resolve("m")
            .unwrap();
        assert_eq!(
            t,
            T {
                c: 40,
                ridge: 0.0,
                features: Features::Lpv,
                delta: Some(0.1)
            }
        );
        let e = Settings::parse(&["cc=4"])
            .unwrap()
            .resolve::<T>("m")
            .unwrap_err()
            .to_string();
        assert!(e.contains("cc") && e.contains("options: c, ridge"), "{e}");
        let e = Settings::parse(&["c=abc"])
            .unwrap()
            .resolve::<T>("m")
            .unwrap_err()
            .to_string();
        assert!(e.contains("option c=abc") && e.contains("int"), "{e}");
        // The CLI words the same error as `--set`.
        let cli = OptionError::invalid("c", 3, "must be at least 4").render("--set");
        assert_eq!(cli, "--set c=3: must be at least 4");
        let e = Settings::parse(&["features=svm"])
            .unwrap()
            .resolve::<T>("m")
            .unwrap_err()
            .to_string();
        assert!(e.contains("features"), "{e}");
        assert!(Settings::parse(&["novalue"]).is_err());
        assert!(Settings::parse(&["c=1", "c=2"]).is_err());
    }

    #[test]
    fn with_sets_one_key_once_and_keeps_the_others() {
        let given = Settings::parse(&["c=40", "features=lpv"]).unwrap();
        let changed = given.with("c", "10").with("delta", "0.1");
        assert_eq!(changed.get("c"), Some("10"));
        assert_eq!(changed.get("features"), Some("lpv"));
        assert_eq!(changed.get("delta"), Some("0.1"));
        assert_eq!(changed.pairs().len(), 3);
        assert_eq!(given.get("c"), Some("40"));
    }

    #[test]
    fn a_preset_is_written_out_under_the_options_given() {
        let paper = [("alternation", "0"), ("c", "none")];
        let pairs = |items: &[&str]| {
            Settings::parse(items)
                .unwrap()
                .with_preset(&paper)
                .map(|s| s.pairs().to_vec())
        };
        let owned = |v: &[(&str, &str)]| -> Vec<(String, String)> {
            v.iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        };
        assert_eq!(
            pairs(&["preset=paper", "c=40"]).unwrap(),
            owned(&[("alternation", "0"), ("c", "40")])
        );
        assert_eq!(
            pairs(&["preset=default", "c=40"]).unwrap(),
            owned(&[("c", "40")])
        );
        assert_eq!(pairs(&["c=40"]).unwrap(), owned(&[("c", "40")]));
        let e = pairs(&["preset=hit"]).unwrap_err();
        assert_eq!(
            e.render("--set"),
            "--set preset=hit: must be default or paper"
        );
        let spec = preset_spec(&paper);
        assert!(spec.doc.contains("alternation=0, c=none"), "{}", spec.doc);
        assert!(preset_spec(&[]).doc.contains("the same as the defaults"));
    }
}
