//! Pieces shared by the data-reader targets.

use hysid_model::data::{DataSelection, RowRange};

/// A data selection chosen by the first byte of the input (decimation 1-4,
/// rows all / `1..` / `..3` / `2..5`), so that `select` is fuzzed too; the
/// rest of the input is the file.
pub fn split(data: &[u8]) -> (DataSelection, &[u8]) {
    let Some((&b, rest)) = data.split_first() else {
        return (DataSelection::default(), data);
    };
    let rows = match (b >> 2) & 3 {
        0 => RowRange::default(),
        1 => RowRange {
            start: Some(1),
            end: None,
        },
        2 => RowRange {
            start: None,
            end: Some(3),
        },
        _ => RowRange {
            start: Some(2),
            end: Some(5),
        },
    };
    let sel = DataSelection {
        decimate: 1 + usize::from(b & 3),
        rows,
        ..DataSelection::default()
    };
    (sel, rest)
}

/// libfuzzer-sys aborts on every panic, even one caught further up. The MAT
/// reader catches panics of the third-party `matrw` parser (and turns them
/// into an error); those are let through here (the first one at each
/// location is logged), while a panic anywhere else still aborts and is
/// reported as a crash.
#[allow(dead_code)]
pub fn tolerate_matrw_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let aborting = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if hysid_io::inside_guarded_parser() {
                if let Some(l) = info.location() {
                    let key = format!("{}:{}", l.file(), l.line());
                    let seen = SEEN.get_or_init(Default::default);
                    if seen
                        .lock()
                        .map(|mut s| s.insert(key.clone()))
                        .unwrap_or(false)
                    {
                        eprintln!("guarded matrw panic (first at this location): {key}: {info}");
                    }
                }
                return;
            }
            aborting(info);
        }));
    });
}

#[allow(dead_code)]
static SEEN: std::sync::OnceLock<std::sync::Mutex<std::collections::HashSet<String>>> =
    std::sync::OnceLock::new();
