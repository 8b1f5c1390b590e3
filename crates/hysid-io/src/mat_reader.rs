//! MATLAB level-5 MAT-file input (compressed or not), through the pure-Rust
//! `matrw` crate. Variables are chosen by name, like CSV columns.

use crate::table::{Available, RawTable};
use hysid_model::data::DataError;
use matrw::MatVariable;
use rayon::prelude::*;
use std::path::Path;

/// The text matrw requires at the start of a level-5 header. The level-5
/// format leaves the 116-byte header text free (MATLAB writes this prefix,
/// `scipy.io.savemat` writes `MATLAB 5.0 MAT-file Platform: ...` without
/// the comma); only the version and endian fields that follow it matter.
const LEVEL5_TEXT: &[u8] = b"MATLAB 5.0 MAT-file, ";

/// Why a file with a MAT-file name is not a level-5 MAT-file (no `IM`/`MI`
/// endian indicator at bytes 126..128), when it says: the HDF5-based
/// MAT-file of `save -v7.3`, a level-4 file ([`level4_header`]), or
/// neither.
fn other_format(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"MATLAB 7.3") || bytes.get(512..520) == Some(b"\x89HDF\r\n\x1a\n") {
        Some(
            "an HDF5-based MAT-file (MATLAB save -v7.3), which is not read here: save it as level 5 \
             (MATLAB: save(file, '-v7'); Python: scipy.io.savemat)",
        )
    } else if matches!(&bytes[126..128], b"IM" | b"MI") {
        None
    } else if level4_header(bytes) {
        Some(
            "a level-4 MAT-file (MATLAB v4 format), which is not read here: save it as level 5 \
             (MATLAB: save(file, '-v7'); Python: scipy.io.savemat without format='4')",
        )
    } else {
        Some("not a MAT-file: neither a level-5 header nor a level-4 matrix header")
    }
}

/// Whether `bytes` start as a level-4 matrix header in either byte order:
/// the type `MOPT` (`M` the byte order 0-4, `O` 0, `P` the number type
/// 0-5, `T` the matrix type 0-2) and the imaginary flag 0 or 1 (MATLAB,
/// "MAT-File Format", level 4).
fn level4_header(bytes: &[u8]) -> bool {
    let word = |at: usize, little: bool| {
        let b: [u8; 4] = bytes[at..at + 4].try_into().unwrap_or_default();
        if little {
            i32::from_le_bytes(b)
        } else {
            i32::from_be_bytes(b)
        }
    };
    [true, false].into_iter().any(|little| {
        let mopt = word(0, little);
        let digit = |d: i32| (mopt / d) % 10;
        (0..=4052).contains(&mopt)
            && digit(100) == 0
            && digit(10) <= 5
            && digit(1) <= 2
            && matches!(word(12, little), 0 | 1)
    })
}

/// The 128-byte header of `bytes` with its text starting as matrw expects
/// it ([`LEVEL5_TEXT`]).
fn standard_header(bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes[..128].to_vec();
    out[..LEVEL5_TEXT.len()].copy_from_slice(LEVEL5_TEXT);
    out
}

/// Reads the variables of `path` named in `wanted` that exist in the file.
/// Each must be a real numeric vector (N x 1 or 1 x N).
pub(crate) fn read(path: &Path, wanted: &[&str]) -> Result<RawTable, DataError> {
    let bytes = std::fs::read(path).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_bytes(&bytes, path, wanted)
}

/// Same as [`read`] on the file's bytes; `path` only names it in errors.
pub(crate) fn read_bytes(
    bytes: &[u8],
    path: &Path,
    wanted: &[&str],
) -> Result<RawTable, DataError> {
    let perr = |location: String, message: String| DataError::Parse {
        path: path.to_path_buf(),
        location,
        message,
    };
    if bytes.len() < 128 {
        return Err(perr(
            String::new(),
            "too short for a MAT-file header (128 bytes)".into(),
        ));
    }
    if let Some(kind) = other_format(bytes) {
        return Err(perr(String::new(), kind.to_string()));
    }
    // matrw trusts the sizes written in the file and reserves them before
    // reading (a 211-byte file found by fuzzing asked for 3.9 GB): check
    // that every element fits inside its parent first. The walk also
    // inflates each compressed variable once, and matrw is given the
    // inflated stream, which it parses as it would the compressed file
    // after inflating it itself.
    let little_endian = &bytes[126..128] != b"MI";
    let mut stream = standard_header(bytes);
    let compressed = check_elements(&bytes[128..], 128, little_endian, 0, Some(&mut stream))
        .map_err(|m| {
            perr(
                String::new(),
                format!("not a readable level-5 MAT-file: {m}"),
            )
        })?;
    let bytes = &stream;
    // matrw also wanders: binrw checks a variable's type only after reading
    // all its fields, and tries nine variable kinds at each position, so it
    // reads names and data at places no declared size leads to (the fifth
    // out-of-memory input from fuzzing). Check every read it could reach.
    check_matrw_reads(&bytes[128..], 128, little_endian, 0).map_err(|m| {
        let offsets = if compressed {
            " (byte offsets of the file with its compressed variables inflated)"
        } else {
            ""
        };
        perr(
            String::new(),
            format!("not a readable level-5 MAT-file: {m}{offsets}"),
        )
    })?;
    // matrw is a third-party parser: a malformed file must still end in an
    // error, never in a crash of the caller.
    let parsed = guarded(|| matrw::load_matfile_from_u8(bytes))
        .ok_or_else(|| perr(String::new(), "not a readable level-5 MAT-file".into()))?
        .map_err(|e| {
            perr(
                String::new(),
                format!("not a readable level-5 MAT-file: {}", plain(&e.to_string())),
            )
        })?;
    // matrw keeps the last of two variables of one name: refuse the file
    // instead of reading either.
    let names = variable_names(&bytes[128..], little_endian);
    if let Some(twice) = wanted
        .iter()
        .find(|w| names.iter().filter(|n| n == *w).count() > 1)
    {
        return Err(perr(
            format!("variable '{twice}': "),
            "appears twice in the file".into(),
        ));
    }
    let mut columns = Vec::new();
    let available: Vec<String> = parsed.iter().map(|(k, _)| k.clone()).collect();
    for (name, var) in parsed.iter() {
        if !wanted.contains(&name.as_str()) {
            continue;
        }
        let loc = format!("variable '{name}': ");
        let unreadable = || perr(loc.clone(), "cannot be read (malformed variable)".into());
        let dim = guarded(|| var.dim()).ok_or_else(unreadable)?;
        if dim.iter().filter(|&&d| d != 1).count() > 1 {
            return Err(perr(
                loc,
                format!("is {dims}, expected a vector", dims = dims(&dim)),
            ));
        }
        // At most one dimension differs from 1, so the product cannot overflow.
        let n: usize = dim.iter().product();
        if guarded(|| var.is_complex()).ok_or_else(unreadable)? == Some(true) {
            return Err(perr(loc, "is complex, expected real values".into()));
        }
        let values = guarded(|| to_f64(var))
            .ok_or_else(unreadable)?
            .ok_or_else(|| perr(loc.clone(), "is not a numeric array".into()))?;
        if values.len() != n {
            return Err(perr(
                loc,
                "data length does not match its dimensions".into(),
            ));
        }
        if let Some(k) = values.iter().position(|v| !v.is_finite()) {
            return Err(perr(
                format!("variable '{name}', row {}: ", k + 1),
                format!("non-finite value {}", values[k]),
            ));
        }
        columns.push((name.clone(), values));
    }
    if columns.is_empty() && available.is_empty() {
        return Err(perr(String::new(), "holds no variable".into()));
    }
    Ok(RawTable {
        path: path.to_path_buf(),
        what: "variable",
        columns,
        available: Available::of(available.iter().map(String::as_str)),
    })
}

/// Nesting depth of miMATRIX elements (cells and structures) checked.
const MAX_DEPTH: usize = 16;
/// Largest ratio of inflated to deflated size (RFC 1951: a 258-byte match
/// in 2 bits at best, about 1032 to 1).
const MAX_DEFLATE_RATIO: usize = 1032;
/// Largest inflated content of a file's miCOMPRESSED elements, all of them
/// together (1 GiB: 134 million doubles).
const MAX_INFLATED: u64 = 1 << 30;

/// The 32-bit word at byte `at` of `buf` in the file's byte order; `None`
/// past the end.
fn u32_at(buf: &[u8], at: usize, le: bool) -> Option<u32> {
    let b: [u8; 4] = buf.get(at..at.checked_add(4)?)?.try_into().ok()?;
    Some(if le {
        u32::from_le_bytes(b)
    } else {
        u32::from_be_bytes(b)
    })
}

/// miMATRIX, an array (variable, cell or structure field).
const MI_MATRIX: u32 = 14;
/// miCOMPRESSED, a zlib stream holding one element.
const MI_COMPRESSED: u32 = 15;

/// One data element of a level-5 stream: its tag at `pos`, the kind read
/// from the low byte of the type (as matrw reads it), and its body
/// `start..end` (the 4 data bytes of a small element).
struct Element {
    pos: usize,
    kind: u32,
    start: usize,
    end: usize,
    /// Where the next element starts.
    next: usize,
}

/// Visits the elements of `buf` one after the other, each checked to fit
/// inside `buf` (see [`check_elements`]), without holding them: an
/// inflated element may hold a hundred million tags.
fn each_element(
    buf: &[u8],
    base: usize,
    le: bool,
    depth: usize,
    mut visit: impl FnMut(Element) -> Result<(), String>,
) -> Result<(), String> {
    // Every tag read below lies inside `buf` (checked before it is read).
    let word = |at: usize| u32_at(buf, at, le).unwrap_or(0);
    let mut pos = 0;
    while pos < buf.len() {
        let rest = buf.len() - pos;
        if rest < 8 {
            // Padding at the end of a parent is fine; a cut tag is not.
            if depth > 0 && buf[pos..].iter().all(|&b| b == 0) {
                break;
            }
            return Err(format!(
                "the element at byte {} is cut ({rest} bytes left, a tag has 8)",
                base + pos
            ));
        }
        // matrw reads the type of a variable from its low byte only: a tag
        // 0x2f0f is compressed to it. Judge the kind the same way.
        let ty = word(pos);
        let kind = ty & 0xff;
        if ty >> 16 != 0 && kind != MI_MATRIX && kind != MI_COMPRESSED {
            // Small data element: type and size in 4 bytes, data in the next 4.
            visit(Element {
                pos,
                kind,
                start: pos + 4,
                end: pos + 8,
                next: pos + 8,
            })?;
            pos += 8;
            continue;
        }
        let n = word(pos + 4) as usize;
        let start = pos + 8;
        if n > buf.len() - start {
            return Err(format!(
                "the element at byte {} declares {n} bytes, only {} remain (truncated or corrupted file)",
                base + pos,
                buf.len() - start
            ));
        }
        let end = start + n;
        let next = if kind == MI_COMPRESSED {
            end
        } else {
            end.next_multiple_of(8).min(buf.len())
        };
        visit(Element {
            pos,
            kind,
            start,
            end,
            next,
        })?;
        pos = next;
    }
    Ok(())
}

/// The names of the variables of `buf` (a file's elements after its
/// header, compressed ones inflated), in order: the array name, the third
/// sub-element of each top-level miMATRIX element ("MAT-File Format",
/// ch. 1), without the padding of a small element. Elements that do not
/// walk give no name; [`check_elements`] has refused them already.
fn variable_names(buf: &[u8], le: bool) -> Vec<String> {
    let mut names = Vec::new();
    let _ = each_element(buf, 128, le, 0, |e| {
        if e.kind == MI_MATRIX {
            let content = &buf[e.start..e.end];
            let mut index = 0;
            let _ = each_element(content, e.start, le, 1, |sub| {
                if index == 2 {
                    let name = String::from_utf8_lossy(&content[sub.start..sub.end]);
                    names.push(name.trim_end_matches('\0').to_string());
                }
                index += 1;
                Ok(())
            });
        }
        Ok(())
    });
    names
}

/// What the miCOMPRESSED element `body` may inflate to: the size its
/// content's tag declares, plus the tag, padded to 8 bytes, but never more
/// than deflate's largest expansion of `body` (about 1032 to 1); `None`
/// when the tag does not inflate.
fn inflated_bound(body: &[u8], le: bool) -> Option<u64> {
    use std::io::Read;
    let mut tag = Vec::with_capacity(8);
    (flate2::read::ZlibDecoder::new(body).take(8))
        .read_to_end(&mut tag)
        .ok()?;
    let most = (body.len() as u64).saturating_mul(MAX_DEFLATE_RATIO as u64);
    Some(
        (u64::from(u32_at(&tag, 4, le)?) + 8)
            .next_multiple_of(8)
            .min(most),
    )
}

/// The inflated content of the miCOMPRESSED element `body` at file byte
/// `at`, at most `bound` bytes ([`inflated_bound`]): the buffer is
/// reserved once, and a stream that inflates past its tag is an error.
fn inflate(body: &[u8], at: usize, bound: Option<u64>) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let fail =
        |e: std::io::Error| format!("the compressed element at byte {at} does not inflate: {e}");
    // Without a bound the tag itself does not inflate: the read says why.
    let limit = bound.unwrap_or(8);
    let mut inflated = Vec::with_capacity(limit as usize);
    (flate2::read::ZlibDecoder::new(body).take(limit + 1))
        .read_to_end(&mut inflated)
        .map_err(fail)?;
    if inflated.len() as u64 > limit {
        return Err(format!(
            "the compressed element at byte {at} inflates past the {limit} bytes its tag declares"
        ));
    }
    Ok(inflated)
}

/// Walks the data elements of a level-5 MAT-file ("MAT-File Format",
/// MathWorks, ch. 1: an 8-byte tag with type and byte count, or a small
/// element packing both in 4 bytes) and checks that every declared size
/// fits inside its parent: the file, an miMATRIX element, or the inflated
/// content of an miCOMPRESSED element. `base` is the offset of `buf` in the
/// file, for the message. The compressed elements of the file (one per
/// variable) are inflated in parallel (rayon). With `out`, the elements are
/// appended to it, each miCOMPRESSED one replaced by its inflated content
/// padded to 8 bytes; returns whether there was one.
fn check_elements(
    buf: &[u8],
    base: usize,
    le: bool,
    depth: usize,
    mut out: Option<&mut Vec<u8>>,
) -> Result<bool, String> {
    if depth > 0 {
        // Nested elements are checked as they come; only the file's own
        // are listed, for their compressed ones to be inflated in parallel.
        each_element(buf, base, le, depth, |e| {
            check_matrix(buf, base, le, depth, &e)
        })?;
        return Ok(false);
    }
    let mut list = Vec::new();
    each_element(buf, base, le, depth, |e| {
        list.push(e);
        Ok(())
    })?;
    let bounds: Vec<Option<u64>> = (list.iter())
        .map(|e| match e.kind {
            MI_COMPRESSED => inflated_bound(&buf[e.start..e.end], le),
            _ => None,
        })
        .collect();
    let declared: u64 = bounds.iter().flatten().sum();
    if declared > MAX_INFLATED {
        return Err(format!(
            "its compressed variables declare {declared} bytes in all, more than the {MAX_INFLATED} read"
        ));
    }
    let inflated: Vec<Option<Result<Vec<u8>, String>>> = (list.par_iter().zip(&bounds))
        .map(|(e, &bound)| {
            (e.kind == MI_COMPRESSED).then(|| inflate(&buf[e.start..e.end], base + e.pos, bound))
        })
        .collect();
    if let Some(out) = out.as_deref_mut() {
        let size = |(e, inflated): (&Element, &Option<Result<Vec<u8>, String>>)| match inflated {
            Some(Ok(v)) => v.len() + 8,
            _ => e.next - e.pos,
        };
        out.reserve(list.iter().zip(&inflated).map(size).sum());
    }
    let mut compressed = false;
    for (e, inflated) in list.iter().zip(inflated) {
        match (e.kind, inflated) {
            (_, Some(inflated)) => {
                let inflated = inflated?;
                check_elements(&inflated, 0, le, depth + 1, None).map_err(|m| {
                    format!("in the compressed element at byte {}: {m}", base + e.pos)
                })?;
                compressed = true;
                if let Some(out) = out.as_deref_mut() {
                    out.extend_from_slice(&inflated);
                    out.resize(out.len().next_multiple_of(8), 0);
                }
                continue;
            }
            _ => check_matrix(buf, base, le, depth, e)?,
        }
        if let Some(out) = out.as_deref_mut() {
            out.extend_from_slice(&buf[e.pos..e.next]);
        }
    }
    Ok(compressed)
}

/// Checks the sub-elements of `e`, an element of `buf`, when it is an
/// miMATRIX element within [`MAX_DEPTH`].
fn check_matrix(
    buf: &[u8],
    base: usize,
    le: bool,
    depth: usize,
    e: &Element,
) -> Result<(), String> {
    if e.kind == MI_MATRIX && depth < MAX_DEPTH {
        // matrw reads an array's sub-elements one after the other without
        // bounding them by the array's own size: check the first five
        // (flags, dimensions, name, data) against all that follows, too.
        check_sequence(&buf[e.start..], base + e.start, le, 5)?;
        check_elements(&buf[e.start..e.end], base + e.start, le, depth + 1, None)?;
    }
    Ok(())
}

/// The first `count` element tags of `buf`, each checked to fit in what
/// follows it (see [`check_elements`]).
fn check_sequence(buf: &[u8], base: usize, le: bool, count: usize) -> Result<(), String> {
    // Every tag read below lies inside `buf` (checked before it is read).
    let word = |at: usize| u32_at(buf, at, le).unwrap_or(0);
    let mut pos = 0;
    for _ in 0..count {
        if buf.len() - pos < 8 {
            return Ok(());
        }
        if word(pos) >> 16 != 0 {
            pos += 8;
            continue;
        }
        let n = word(pos + 4) as usize;
        let left = buf.len() - pos - 8;
        if n > left {
            return Err(format!(
                "the element at byte {} declares {n} bytes, only {left} remain (truncated or corrupted file)",
                base + pos
            ));
        }
        pos = (pos + 8 + n).next_multiple_of(8).min(buf.len());
    }
    Ok(())
}

/// Nesting depth of compressed elements followed by [`check_matrw_reads`].
const MAX_COMPRESSED_DEPTH: usize = 4;

/// Checks that no read `matrw` 0.1.4 could make in `buf` (the bytes after
/// the header, or an inflated miCOMPRESSED element) reserves more memory
/// than there are bytes left.
///
/// matrw (through binrw) reserves the declared byte count of a `Vec<u8>`
/// before reading it: an array name (`miINT8`, normal format) and `miUINT8`
/// or `miUTF8` array data. Every such read follows an array-flags
/// sub-element (`miUINT32`, 8 bytes, a valid class) 8 bytes after the start
/// of a variable, since all of matrw's variable kinds but "compressed" and
/// "empty" begin with it. Which positions matrw tries as variables depends on
/// the contents, so every position with that signature is taken as a
/// possible variable and the reads that would follow are checked: the name
/// right after the flags (objects), or dimensions then name then data (one
/// or two data elements, or sparse row and column indices then data). Other
/// reads grow their buffers as bytes arrive, so the file bounds them.
/// Compressed elements matrw may reach are inflated and checked the same
/// way. Positions are relative to `buf`, which starts at a multiple of 8 of
/// matrw's stream, as its alignment needs.
fn check_matrw_reads(buf: &[u8], origin: usize, le: bool, depth: usize) -> Result<(), String> {
    let at = |i: usize, w: usize| buf.get(i..i.checked_add(w)?);
    let u16e = |i: usize| {
        at(i, 2).map(|b| {
            let b = [b[0], b[1]];
            if le {
                u16::from_le_bytes(b)
            } else {
                u16::from_be_bytes(b)
            }
        })
    };
    let u32e = |i: usize| u32_at(buf, i, le);
    let byte = |i: usize| buf.get(i).copied();
    let left = |i: usize| buf.len().saturating_sub(i);
    let align = |i: usize| i.next_multiple_of(8);
    // The end of a dimensions element (miINT32, normal then small format) at
    // `d`, or None when matrw cannot read one there.
    let dims = |d: usize| -> Option<usize> {
        if byte(d)? != 5 {
            return None;
        }
        if u16e(d + 2)? == 0 {
            let n = (u32e(d + 4)? / 4) as usize * 4;
            if n <= left(d + 8) {
                return Some(d + 8 + n);
            }
        }
        let n = (u16e(d + 2)? / 4) as usize * 4;
        (n <= left(d + 4)).then_some(d + 4 + n)
    };
    let too_big = |what: &str, i: usize, n: u32| {
        format!(
            "the {what} at byte {} declares {n} bytes, only {} remain (truncated or corrupted file)",
            origin + i,
            left(i + 8)
        )
    };
    // The end of an array name at `q`; an error if matrw would reserve more
    // than what is left.
    let name = |q: usize| -> Result<Option<usize>, String> {
        if byte(q) != Some(1) {
            return Ok(None);
        }
        // The empty name: a 64-bit 1 whose first byte is the type.
        if le && at(q, 8) == Some(&[1, 0, 0, 0, 0, 0, 0, 0][..]) {
            return Ok(Some(q + 1));
        }
        if u16e(q + 2) == Some(0)
            && let Some(n) = u32e(q + 4)
        {
            if n as usize > left(q + 8) {
                return Err(too_big("array name", q, n));
            }
            return Ok(Some(q + 8 + (n as usize).max(8)));
        }
        Ok(u16e(q + 2)
            .map(usize::from)
            .filter(|&n| n <= left(q + 4))
            .map(|n| q + 4 + n.max(4)))
    };
    // The end of an array data element at `r`, same contract. matrw reads
    // the values little-endian whatever the file says, but the tag in the
    // file's order.
    let data = |r: usize| -> Result<Option<usize>, String> {
        let Some(ty) = byte(r) else { return Ok(None) };
        let width = match ty {
            1 | 2 | 16 => 1,
            3 | 4 | 17 => 2,
            5..=7 => 4,
            9 | 12 | 13 => 8,
            _ => return Ok(None),
        };
        if u16e(r + 2) == Some(0)
            && let Some(n) = u32e(r + 4)
        {
            if width == 1 && ty != 1 && n as usize > left(r + 8) {
                return Err(too_big("array data element", r, n));
            }
            let n = n as usize / width * width;
            if n <= left(r + 8) {
                return Ok(Some(r + 8 + n));
            }
        }
        Ok(u16e(r + 2)
            .map(|n| usize::from(n) / width * width)
            .filter(|&n| n <= left(r + 4))
            .map(|n| r + 4 + n))
    };
    // Every position is independent: runs of positions are checked in
    // parallel (rayon), and the first error in file order is reported.
    let check_at = |p: usize| -> Result<(), String> {
        if byte(p) == Some(15)
            && let Some(n) = u32e(p + 4)
        {
            check_compressed_candidate(&buf[p + 8..], n, le, depth, origin + p)?;
        }
        let flags = byte(p + 8) == Some(6)
            && u32e(p + 12) == Some(8)
            && byte(p + 16).is_some_and(|c| (1..=17).contains(&c));
        if !flags {
            return Ok(());
        }
        // Objects: name, 8 bytes, class name.
        if let Some(end) = name(p + 24)? {
            name(align(end) + 8)?;
        }
        // Everything else: dimensions, name, then data.
        let Some(end) = dims(p + 24) else {
            return Ok(());
        };
        let Some(end) = name(align(end))? else {
            return Ok(());
        };
        let r = align(end);
        if let Some(end) = data(r)? {
            data(align(end))?;
        }
        if let Some(ir) = dims(r)
            && let Some(jc) = dims(align(ir))
        {
            data(align(jc))?;
        }
        Ok(())
    };
    const RUN: usize = 1 << 20;
    let last = buf.len().saturating_sub(8);
    (0..last.div_ceil(RUN))
        .into_par_iter()
        .map(|r| (r * RUN..((r + 1) * RUN).min(last)).try_for_each(&check_at))
        .collect::<Vec<_>>()
        .into_iter()
        .collect()
}

/// A miCOMPRESSED variable matrw may find at byte `at` (`body` follows its
/// tag, which declares `n` bytes): matrw inflates it and parses the result,
/// so check that too (see [`check_matrw_reads`]). Bodies that do not
/// inflate make matrw fail (or panic, which the reader catches), nothing to
/// check there.
fn check_compressed_candidate(
    body: &[u8],
    n: u32,
    le: bool,
    depth: usize,
    at: usize,
) -> Result<(), String> {
    use std::io::Read;
    // A zlib stream starts with a deflate method byte and a header checksum.
    if body.len() < 2
        || body[0] & 0x0f != 8
        || (u16::from(body[0]) << 8 | u16::from(body[1])) % 31 != 0
    {
        return Ok(());
    }
    let body = &body[..body.len().min(n as usize)];
    let mut inflated = Vec::new();
    if flate2::read::ZlibDecoder::new(body)
        .take(MAX_INFLATED)
        .read_to_end(&mut inflated)
        .is_err()
    {
        return Ok(());
    }
    if depth >= MAX_COMPRESSED_DEPTH {
        return Err(format!(
            "compressed elements nested more than {MAX_COMPRESSED_DEPTH} deep at byte {at}"
        ));
    }
    // Offsets inside are counted from the start of the inflated bytes.
    check_matrw_reads(&inflated, 0, le, depth + 1)
        .map_err(|e| format!("in the compressed element at byte {at} (inflated): {e}"))
}

thread_local! {
    static IN_GUARDED_PARSER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// True while the current thread runs third-party parser code whose panics
/// the MAT reader catches and turns into a [`DataError`]. A program's panic
/// hook can stay silent then (the `hysid` CLI does), so that a malformed
/// file gives one error line, not a panic report followed by it.
pub fn inside_guarded_parser() -> bool {
    IN_GUARDED_PARSER.with(std::cell::Cell::get)
}

/// Runs `f` (matrw code), `None` if it panicked.
fn guarded<T>(f: impl FnOnce() -> T) -> Option<T> {
    struct Reset(bool);
    impl Drop for Reset {
        fn drop(&mut self) {
            IN_GUARDED_PARSER.with(|g| g.set(self.0));
        }
    }
    let _reset = Reset(IN_GUARDED_PARSER.with(|g| g.replace(true)));
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).ok()
}

/// matrw's errors come from binrw with terminal colours, box-drawing rules
/// and a backtrace of the parser's source files; keep the words only
/// ("no variants matched at 0x0 While parsing field 'matfile_ver' in
/// MatFileHeader").
fn plain(message: &str) -> String {
    let mut text = String::with_capacity(message.len());
    let mut chars = message.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            // An ANSI escape sequence: ESC [ parameters final-letter.
            if chars.peek() == Some(&'[') {
                chars.next();
                for c in chars.by_ref() {
                    if c.is_ascii_alphabetic() {
                        break;
                    }
                }
            }
            continue;
        }
        if ('\u{2500}'..='\u{257f}').contains(&c) || c.is_control() {
            text.push(' ');
        } else {
            text.push(c);
        }
    }
    let words: Vec<&str> = text
        .split_whitespace()
        .filter(|w| !matches!(*w, "Backtrace" | "binrw" | "error" | "0:" | "Error:"))
        .collect();
    // Drop the parser's own source locations (" at /.../header.rs:87").
    let mut kept = Vec::with_capacity(words.len());
    let mut i = 0;
    while i < words.len() {
        if words[i] == "at" && words.get(i + 1).is_some_and(|w| w.contains(".rs:")) {
            i += 2;
            continue;
        }
        kept.push(words[i]);
        i += 1;
    }
    // binrw lists every variant it tried ("... ObjectMCOS no variants
    // matched ..."): the first clause says where the file stops making sense.
    const MAX_WORDS: usize = 16;
    let mut first = Vec::new();
    for w in kept {
        if let Some(w) = w.strip_suffix("...") {
            first.push(w);
            break;
        }
        first.push(w);
        if first.len() == MAX_WORDS {
            break;
        }
    }
    if first.is_empty() {
        "malformed file".into()
    } else {
        first.join(" ")
    }
}

fn dims(d: &[usize]) -> String {
    d.iter().map(usize::to_string).collect::<Vec<_>>().join("x")
}

fn widen<T: Into<f64>>(v: Option<Vec<T>>) -> Option<Vec<f64>> {
    v.map(|x| x.into_iter().map(Into::into).collect())
}

/// Any real numeric class, widened to f64.
fn to_f64(v: &MatVariable) -> Option<Vec<f64>> {
    v.to_vec_f64()
        .or_else(|| widen(v.to_vec_f32()))
        .or_else(|| widen(v.to_vec_i32()))
        .or_else(|| widen(v.to_vec_i16()))
        .or_else(|| widen(v.to_vec_i8()))
        .or_else(|| widen(v.to_vec_u8()))
        .or_else(|| widen(v.to_vec_u16()))
        .or_else(|| widen(v.to_vec_u32()))
}

#[cfg(test)]
mod tests {
    use crate::load;
    use hysid_model::data::DataSelection;
    use matrw::{MatFile, matvar};

    fn write(compress: bool, y: Vec<f64>) -> tempfile::TempPath {
        let path = tempfile::Builder::new()
            .suffix(".mat")
            .tempfile()
            .unwrap()
            .into_temp_path();
        let mut m = MatFile::new();
        m.insert("u", matvar!(vec![1.0, 2.0, 3.0]));
        m.insert("y", matvar!(y));
        matrw::save_matfile_v7(path.to_str().unwrap(), m, compress).unwrap();
        path
    }

    #[test]
    fn reads_compressed_and_uncompressed() {
        for compress in [false, true] {
            let p = write(compress, vec![4.0, 5.0, 6.0]);
            let d = load(&p, &DataSelection::default()).unwrap();
            assert_eq!(d.y(), &[4.0, 5.0, 6.0]);
            assert_eq!(d.u(0), &[1.0, 2.0, 3.0]);
            assert_eq!(d.ts, None);
        }
    }

    /// A file holding two variables of one name is refused (matrw would
    /// keep one of them), compressed or not.
    #[test]
    fn a_variable_named_twice_is_refused() {
        for compress in [false, true] {
            let p = write(compress, vec![4.0, 5.0, 6.0]);
            let bytes = std::fs::read(&p).unwrap();
            let mut twice = bytes.clone();
            twice.extend_from_slice(&bytes[128..]);
            let e = crate::load_bytes(
                &twice,
                crate::DataFormat::Mat,
                std::path::Path::new("twice.mat"),
                &DataSelection::default(),
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains("twice.mat: variable '"), "{e}");
            assert!(e.contains("appears twice in the file"), "{e}");
        }
    }

    #[test]
    fn missing_variable_and_non_finite_are_named() {
        let p = write(false, vec![4.0, f64::INFINITY, 6.0]);
        let e = load(&p, &DataSelection::default()).unwrap_err().to_string();
        assert!(
            e.contains("variable 'y', row 2") && e.contains("non-finite"),
            "{e}"
        );
        let sel = DataSelection {
            output: "z".into(),
            ..Default::default()
        };
        let p = write(false, vec![4.0, 5.0, 6.0]);
        let e = load(&p, &sel).unwrap_err().to_string();
        assert!(e.contains("no variable 'z'") && e.contains("u"), "{e}");
    }

    #[test]
    fn parser_errors_are_plain_words() {
        let raw = "binrw error\n\u{1b}[1m\u{2578}\u{2501}\u{2505} Backtrace \u{2505}\n 0: \u{1b}[1mError: no variants matched at 0x0\u{1b}[22m\n \u{1b}[1mWhile parsing field 'matfile_ver' in MatFileHeader\u{1b}[22m at /root/.cargo/registry/src/matrw-0.1.4/src/parser/header.rs:87\n\u{2578}\u{2501}";
        assert_eq!(
            super::plain(raw),
            "no variants matched at 0x0 While parsing field 'matfile_ver' in MatFileHeader"
        );
        assert_eq!(super::plain("\u{1b}[1m\u{2501}"), "malformed file");
        let tried_everything = "no variants matched at 0xb8... ObjectMCOS no variants matched at 0xb8 Unexpected value for enum: 0 1: While parsing field 'data_type'";
        assert_eq!(
            super::plain(tried_everything),
            "no variants matched at 0xb8"
        );
    }

    #[test]
    fn fuzzer_crash_inputs_are_errors() {
        // A dimension product that overflows inside matrw (fuzz target
        // mat_reader; the first byte chose the selection there).
        let bytes = include_bytes!("../tests/data/fuzz/mat_reader-mul-overflow-4ed3ecb8");
        let e = crate::load_bytes(
            &bytes[1..],
            crate::DataFormat::Mat,
            std::path::Path::new("crash.mat"),
            &DataSelection::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("crash.mat: not a readable level-5 MAT-file"),
            "{e}"
        );
        assert!(!crate::inside_guarded_parser());
    }

    #[test]
    fn sizes_beyond_the_parent_are_refused_before_matrw_allocates() {
        // A 211-byte file whose array-name element declares ~4 GB (fuzz
        // target mat_reader, libFuzzer out-of-memory).
        // A 649-byte one whose compressed array's data element asks for
        // 3.3 GB, beyond what the array itself declares.
        // An 881-byte one where matrw, trying its object kinds on an element
        // of type miUTF32, reads an array name declaring 4.29 GB at a place
        // no declared size leads to.
        for bytes in [
            &include_bytes!("../tests/data/fuzz/mat_reader-oom-33af7a43")[..],
            &include_bytes!("../tests/data/fuzz/mat_reader-oom-a139648a")[..],
            &include_bytes!("../tests/data/fuzz/mat_reader-oom-68e4e61d")[..],
        ] {
            let e = crate::load_bytes(
                &bytes[1..],
                crate::DataFormat::Mat,
                std::path::Path::new("oom.mat"),
                &DataSelection::default(),
            )
            .unwrap_err()
            .to_string();
            assert!(
                e.contains("declares") && e.contains("remain") || e.contains("does not inflate"),
                "{e}"
            );
        }
        // The real record and matrw's own files pass both checks.
        let record = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/pick-and-place/headdata_1v6.mat"
        );
        let mut files = vec![std::fs::read(record).unwrap()];
        for compress in [false, true] {
            let p = write(compress, vec![4.0, 5.0, 6.0]);
            files.push(std::fs::read(&p).unwrap());
        }
        for b in files {
            super::check_elements(&b[128..], 128, true, 0, None).unwrap();
            super::check_matrw_reads(&b[128..], 128, true, 0).unwrap();
        }
    }

    /// A compressed element inflates to at most what its tag declares,
    /// and the file's compressed elements to at most 1 GiB together: a
    /// kilobyte of zeros declaring more, and a megabyte declaring 2 GiB,
    /// are refused without inflating them whole.
    #[test]
    fn inflation_is_bounded_by_the_tags_and_in_all() {
        use std::io::Write;
        let deflated = |content: &[u8], junk: usize| {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
            z.write_all(content).unwrap();
            let mut body = z.finish().unwrap();
            body.extend(std::iter::repeat_n(0x5a, junk));
            body
        };
        let file = |body: &[u8]| {
            let mut b = vec![b' '; 116];
            b.extend([0; 8]);
            b.extend(0x0100u16.to_le_bytes());
            b.extend(b"IM");
            b.extend(15u32.to_le_bytes());
            b.extend((body.len() as u32).to_le_bytes());
            b.extend(body);
            b
        };
        // A tag declaring 16 bytes, then 1024 zeros.
        let mut past = 14u32.to_le_bytes().to_vec();
        past.extend(16u32.to_le_bytes());
        past.extend([0; 1024]);
        let e = super::check_elements(&file(&deflated(&past, 0))[128..], 128, true, 0, None);
        assert_eq!(
            e.unwrap_err(),
            "the compressed element at byte 128 inflates past the 24 bytes its tag declares"
        );
        // A tag declaring 2 GiB, in a body that could inflate to that much.
        let mut huge = 14u32.to_le_bytes().to_vec();
        huge.extend((1u32 << 31).to_le_bytes());
        let body = deflated(&huge, 1 << 20);
        let e = super::check_elements(&file(&body)[128..], 128, true, 0, None).unwrap_err();
        // Deflate's largest expansion of the body bounds the tag's 2 GiB.
        let bound = body.len() * super::MAX_DEFLATE_RATIO;
        assert_eq!(
            e,
            format!(
                "its compressed variables declare {bound} bytes in all, more than the 1073741824 read"
            )
        );
    }

    #[test]
    fn reads_matrw_could_reach_are_checked() {
        // An uncompressed double vector named "y", then the same with its
        // name declaring 2^32 - 1 bytes, then with its data retyped miUINT8
        // and declaring 2^32 - 1 bytes, then a zeroed variable tag (matrw
        // still tries it as an object) in front of a too-long name.
        let mut ok = Vec::new();
        let w = |v: &mut Vec<u8>, x: u32| v.extend_from_slice(&x.to_le_bytes());
        w(&mut ok, 14);
        w(&mut ok, 56);
        for x in [6, 8, 6, 0, 5, 8, 1, 1, 0x0001_0001, u32::from(b'y'), 9, 8] {
            w(&mut ok, x);
        }
        ok.extend_from_slice(&2.5f64.to_le_bytes());
        super::check_matrw_reads(&ok, 128, true, 0).unwrap();
        let mut long_name = ok.clone();
        long_name[40..44].copy_from_slice(&[1, 0, 0, 0]);
        long_name[44..48].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = super::check_matrw_reads(&long_name, 128, true, 0).unwrap_err();
        assert!(
            e.starts_with("the array name at byte 168 declares 4294967295 bytes"),
            "{e}"
        );
        let mut long_data = ok.clone();
        long_data[48] = 2;
        long_data[52..56].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = super::check_matrw_reads(&long_data, 128, true, 0).unwrap_err();
        assert!(e.starts_with("the array data element at byte 176"), "{e}");
        let mut wanderer = long_name.clone();
        wanderer[..8].fill(0);
        assert!(super::check_matrw_reads(&wanderer, 128, true, 0).is_err());
    }

    #[test]
    fn garbage_is_an_error_not_a_crash() {
        let mut bytes = vec![0u8; 300];
        bytes[..6].copy_from_slice(b"MATLAB");
        let path = tempfile::Builder::new()
            .suffix(".mat")
            .tempfile()
            .unwrap()
            .into_temp_path();
        std::fs::write(&path, &bytes).unwrap();
        assert!(load(&path, &DataSelection::default()).is_err());
        std::fs::write(&path, b"short").unwrap();
        assert!(load(&path, &DataSelection::default()).is_err());
    }
}
