//! YAML reading helpers (on yaml-rust2's DOM) that name the key at fault, number formatting
//! for writers, and atomic file writes.
//!
//! Before the DOM is built, the text is run through yaml-rust2's event parser alone, which
//! holds no document: an alias (`*name`) is refused there ([`CameraFileError::YamlAlias`]), because
//! the loader copies the aliased node at every use (a 335-byte "billion laughs" file of nine
//! levels of nine aliases grew to 8 GB in 60 s); so is nesting deeper than [`MAX_YAML_DEPTH`]
//! ([`CameraFileError::YamlTooDeep`]). Anchors alone are harmless and accepted.

use std::path::Path;

use yaml_rust2::parser::{Event, Parser};
use yaml_rust2::scanner::ScanError;
use yaml_rust2::{Yaml, YamlLoader};

use crate::error::CameraFileError;

/// The deepest nesting of sequences and mappings accepted: 32. The deepest real camera file
/// nests 4 levels (document, `camN`, `T_cn_cnm1`, a row); without a bound, 600 kB of
/// `- - - ...` (300 000 levels) overflows the stack in yaml-rust2's loader and aborts the
/// process (measured with yaml-rust2 0.13).
pub const MAX_YAML_DEPTH: usize = 32;

/// Parse the first YAML document of `text`. Leading `%` directive lines are dropped first:
/// OpenCV (and so CamOdoCal) writes `%YAML:1.0`, which is not a valid YAML 1.2 directive.
/// Line numbers in errors count the dropped lines, so they are lines of `text`.
pub fn parse(text: &str) -> Result<Yaml, CameraFileError> {
    let mut body = text.trim_start_matches('\u{feff}');
    loop {
        let trimmed = body.trim_start_matches([' ', '\t', '\r', '\n']);
        if trimmed.starts_with('%') {
            body = trimmed.split_once('\n').map_or("", |(_, rest)| rest);
        } else {
            body = trimmed;
            break;
        }
    }
    // `body` is a suffix of `text`: the lines before it were dropped.
    let dropped_lines = text[..text.len() - body.len()].matches('\n').count();
    check_events(body, dropped_lines)?;
    let docs = YamlLoader::load_from_str(body).map_err(|e| syntax_error(&e, dropped_lines))?;
    match docs.into_iter().next() {
        None | Some(Yaml::Null) => Err(CameraFileError::Empty),
        Some(doc) => Ok(doc),
    }
}

/// Refuses YAML text that a DOM loader would expand without bound, before it is loaded: any
/// alias (`*name`: yaml-rust2's loader copies the aliased node at every use, so a 335-byte
/// "billion laughs" file grows to gigabytes) and nesting deeper than [`MAX_YAML_DEPTH`]
/// (which overflows the loader's stack). The event parser it runs holds no document. The
/// readers of this crate call it; other YAML readers of the same files (scenario files that
/// embed rigs, say) should too.
///
/// # Errors
/// [`CameraFileError::YamlAlias`] or [`CameraFileError::YamlTooDeep`] with the line, or
/// [`CameraFileError::Yaml`] for a syntax error.
pub fn check_yaml_input(text: &str) -> Result<(), CameraFileError> {
    check_events(text, 0)
}

/// Run the event parser over `body` (which holds no document, so it takes no memory beyond
/// the current event) and refuse the first alias and any nesting deeper than
/// [`MAX_YAML_DEPTH`].
fn check_events(body: &str, dropped_lines: usize) -> Result<(), CameraFileError> {
    let mut parser = Parser::new_from_str(body);
    let mut depth = 0usize;
    loop {
        let (event, mark) = parser
            .next_token()
            .map_err(|e| syntax_error(&e, dropped_lines))?;
        let line = mark.line() + dropped_lines;
        match event {
            Event::StreamEnd => return Ok(()),
            Event::Alias(_) => return Err(CameraFileError::YamlAlias { line }),
            Event::SequenceStart(..) | Event::MappingStart(..) => {
                depth += 1;
                if depth > MAX_YAML_DEPTH {
                    return Err(CameraFileError::YamlTooDeep {
                        line,
                        limit: MAX_YAML_DEPTH,
                    });
                }
            }
            Event::SequenceEnd | Event::MappingEnd => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
}

/// A syntax error with its line counted in the original text.
fn syntax_error(e: &ScanError, dropped_lines: usize) -> CameraFileError {
    CameraFileError::Yaml {
        message: format!(
            "{} at line {} column {}",
            e.info(),
            e.marker().line() + dropped_lines,
            e.marker().col() + 1
        ),
    }
}

/// Join a parent path and a key for messages (`projection_parameters.mu`).
pub fn join(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_owned()
    } else {
        format!("{parent}.{key}")
    }
}

/// The value of `key` in the mapping `node` (whose path is `path`).
pub fn get<'a>(node: &'a Yaml, path: &str, key: &str) -> Result<&'a Yaml, CameraFileError> {
    let Yaml::Hash(h) = node else {
        return Err(CameraFileError::WrongType {
            key: if path.is_empty() {
                "(document)".to_owned()
            } else {
                path.to_owned()
            },
            expected: "a mapping",
        });
    };
    h.get(&Yaml::String(key.to_owned()))
        .ok_or_else(|| CameraFileError::MissingKey {
            key: join(path, key),
        })
}

/// The value of `key` if present.
pub fn get_opt<'a>(node: &'a Yaml, key: &str) -> Option<&'a Yaml> {
    match node {
        Yaml::Hash(h) => h.get(&Yaml::String(key.to_owned())),
        _ => None,
    }
}

/// A number (YAML real or integer).
pub fn number(node: &Yaml, key: &str) -> Result<f64, CameraFileError> {
    match node {
        Yaml::Real(_) => node.as_f64(),
        #[allow(clippy::cast_precision_loss)] // file integers are small sizes and coefficients
        Yaml::Integer(i) => Some(*i as f64),
        _ => None,
    }
    .ok_or_else(|| CameraFileError::WrongType {
        key: key.to_owned(),
        expected: "a number",
    })
}

/// `node[key]` as a number.
pub fn number_at(node: &Yaml, path: &str, key: &str) -> Result<f64, CameraFileError> {
    number(get(node, path, key)?, &join(path, key))
}

/// A non-negative integer that fits in u32.
pub fn unsigned(node: &Yaml, key: &str) -> Result<u32, CameraFileError> {
    node.as_i64()
        .and_then(|i| u32::try_from(i).ok())
        .ok_or_else(|| CameraFileError::WrongType {
            key: key.to_owned(),
            expected: "a non-negative integer",
        })
}

/// A string (a YAML scalar that is a string; numbers are accepted and printed back).
pub fn string(node: &Yaml, key: &str) -> Result<String, CameraFileError> {
    match node {
        Yaml::String(s) | Yaml::Real(s) => Ok(s.clone()),
        Yaml::Integer(i) => Ok(i.to_string()),
        Yaml::Null => Ok(String::new()),
        _ => Err(CameraFileError::WrongType {
            key: key.to_owned(),
            expected: "a string",
        }),
    }
}

/// A list of exactly `N` numbers.
pub fn numbers<const N: usize>(
    node: &Yaml,
    key: &str,
    expected: &'static str,
) -> Result<[f64; N], CameraFileError> {
    let wrong = || CameraFileError::WrongType {
        key: key.to_owned(),
        expected,
    };
    let Yaml::Array(items) = node else {
        return Err(wrong());
    };
    if items.len() != N {
        return Err(wrong());
    }
    let mut out = [0.0; N];
    for (o, item) in out.iter_mut().zip(items) {
        *o = number(item, key).map_err(|_| wrong())?;
    }
    Ok(out)
}

/// A number with 17 significant digits (enough to round-trip any f64), in C's `%.16e` form
/// (`-1.6480000000000000e-02`): a signed, two-digit exponent, which YAML 1.1 readers such as
/// PyYAML (Kalibr) need to see a float, and which OpenCV writes too.
pub fn fmt_f64(x: f64) -> String {
    let s = format!("{x:.16e}");
    match s.split_once('e') {
        Some((mantissa, exp)) => {
            let (sign, digits) = match exp.strip_prefix('-') {
                Some(d) => ('-', d),
                None => ('+', exp),
            };
            format!("{mantissa}e{sign}{digits:0>2}")
        }
        // NaN and infinities never reach the writers (parameters are validated finite).
        None => s,
    }
}

/// A string as a YAML scalar: plain when it is safe, double-quoted with escapes otherwise.
pub fn fmt_str(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '/' | '_' | '-' | '.'))
        && !s.starts_with(['-', '.'])
        && s.parse::<f64>().is_err()
        && !matches!(
            s.to_ascii_lowercase().as_str(),
            "true" | "false" | "null" | "yes" | "no" | "on" | "off"
        );
    if plain {
        return s.to_owned();
    }
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            c if c.is_control() => out.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The largest camera file read, in bytes: 1 MiB. A Kalibr camchain of ten cameras with IMU
/// fields is about 8 kB and a CamOdoCal camera YAML about 600 bytes, so the limit is more than
/// a hundred times any real file and still small enough to hold in memory without thought.
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// Read a camera file: a regular file of at most [`MAX_FILE_BYTES`] of UTF-8 text
/// ([`crate::io::read_text`]).
pub fn read_text(path: &Path) -> Result<String, CameraFileError> {
    Ok(crate::io::read_text(path, MAX_FILE_BYTES)?)
}

/// Write `contents` to `path` atomically ([`crate::io::write_atomically`]).
pub fn write_atomic(path: &Path, contents: &str) -> Result<(), CameraFileError> {
    Ok(crate::io::write_atomically(path, contents.as_bytes())?)
}
