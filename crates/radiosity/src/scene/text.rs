//! Reading the scene's text files, and showing their text in messages:
//! shared by the OBJ reader ([`super::obj`]) and the MTL reader
//! ([`super::mtl`]); the message helpers are also used by the `#@camera`
//! directive and `--camera` ([`super::Camera::parse`]) and by the sensor
//! points file ([`crate::sensors`]).
//!
//! OBJ and MTL are plain text, and bad input gets one message naming the
//! file and line (design.md section 6). A file's bytes are text when they
//! are UTF-8, after an optional byte-order mark; NUL bytes (a binary file
//! given by mistake), UTF-16 and invalid UTF-8 are refused with the line
//! where they are ([`decode`]). Lines end with LF, CR LF or CR alone (old
//! Mac files), a backslash at the end of a line continues it on the next,
//! and every line is bounded by
//! [`Limits::max_line_bytes`](super::Limits::max_line_bytes). Numbers must
//! be finite. Input text in a message is quoted, escaped and cut to a
//! readable length ([`quoted`]), and lengths are shown in a unit read at a
//! glance.

use std::borrow::Cow;
use std::fmt::Write as _;
use std::path::Path;

use super::{Limits, Location, SceneError};

/// Turns a file's bytes into text: a UTF-8 byte-order mark is skipped;
/// NUL bytes (binary data), UTF-16 and invalid UTF-8 are refused with the
/// line where they are.
pub fn decode<'a>(path: &Path, bytes: &'a [u8]) -> Result<Cow<'a, str>, SceneError> {
    let invalid = |line: Option<usize>, message: String| SceneError::Invalid {
        location: Location {
            path: path.to_path_buf(),
            line,
        },
        message,
    };
    if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
        return Err(invalid(
            None,
            "the file is UTF-16 text: save it as UTF-8 (or ASCII)".into(),
        ));
    }
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let line_of = |offset: usize| line_number(&bytes[..offset]);
    if let Some(offset) = bytes.iter().position(|&b| b == 0) {
        return Err(invalid(
            Some(line_of(offset)),
            "a NUL byte: this looks like a binary file, not Wavefront OBJ/MTL text".into(),
        ));
    }
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok(Cow::Borrowed(text)),
        Err(e) => Err(invalid(
            Some(line_of(e.valid_up_to())),
            format!(
                "byte 0x{:02X} is not UTF-8 text: save the file as UTF-8",
                bytes[e.valid_up_to()]
            ),
        )),
    }
}

/// The 1-based line that starts after `before`, counting LF, CR LF and lone
/// CR as line ends (as [`logical_lines`] does).
fn line_number(before: &[u8]) -> usize {
    let mut line = 1;
    let mut previous = 0u8;
    for &b in before {
        if b == b'\n' && previous != b'\r' || b == b'\r' {
            line += 1;
        }
        previous = b;
    }
    line
}

/// Lines of `text` ending in LF, CR LF or a lone CR, with backslash
/// continuations joined: `(first line number, text)`. Each physical and
/// logical line is checked against `limits.max_line_bytes`.
pub(super) fn logical_lines<'a>(
    path: &'a Path,
    text: &'a str,
    limits: &'a Limits,
) -> impl Iterator<Item = Result<(usize, Cow<'a, str>), SceneError>> + 'a {
    let mut rest = text;
    let mut next_line = 1;
    let too_long = move |line: usize, bytes: usize| SceneError::Invalid {
        location: Location::line(path, line),
        message: format!(
            "the line is {bytes} bytes long, more than the limit of {} bytes \
             (raise it with --max-line-length)",
            limits.max_line_bytes
        ),
    };
    std::iter::from_fn(move || {
        if rest.is_empty() {
            return None;
        }
        let start = next_line;
        let mut joined: Option<String> = None;
        loop {
            let end = rest.find(['\n', '\r']).unwrap_or(rest.len());
            let line = &rest[..end];
            let after = match rest.as_bytes().get(end) {
                Some(b'\r') if rest.as_bytes().get(end + 1) == Some(&b'\n') => end + 2,
                Some(_) => end + 1,
                None => end,
            };
            rest = &rest[after..];
            next_line += 1;
            if line.len() > limits.max_line_bytes {
                return Some(Err(too_long(next_line - 1, line.len())));
            }
            match (line.strip_suffix('\\'), joined.as_mut()) {
                (Some(head), _) if !rest.is_empty() => {
                    let acc = joined.get_or_insert_with(String::new);
                    acc.push_str(head);
                    acc.push(' ');
                    if acc.len() > limits.max_line_bytes {
                        return Some(Err(too_long(start, acc.len())));
                    }
                }
                (head, Some(acc)) => {
                    acc.push_str(head.unwrap_or(line));
                    if acc.len() > limits.max_line_bytes {
                        return Some(Err(too_long(start, acc.len())));
                    }
                    return Some(Ok((start, Cow::Owned(joined.take().unwrap_or_default()))));
                }
                (head, None) => return Some(Ok((start, Cow::Borrowed(head.unwrap_or(line))))),
            }
        }
    })
}

/// Input text for a message: quoted, control characters escaped, cut to a
/// readable length.
#[must_use]
pub fn quoted(text: &str) -> String {
    const SHOWN: usize = 40;
    let mut out = String::from("'");
    for (i, c) in text.chars().enumerate() {
        if i == SHOWN {
            let _ = write!(out, "...' ({} bytes)", text.len());
            return out;
        }
        out.extend(c.escape_debug());
    }
    out.push('\'');
    out
}

/// A length in metres for a message, in a unit a person reads at a glance.
pub(crate) fn length(metres: f64) -> String {
    if metres >= 1.0 {
        format!("{metres:.3} m")
    } else if metres >= 0.01 {
        format!("{:.1} cm", metres * 100.0)
    } else if metres >= 1e-4 {
        format!("{:.2} mm", metres * 1000.0)
    } else {
        format!("{metres:.2e} m")
    }
}

/// Parses a finite number, with a message naming the token.
pub(super) fn number(token: &str) -> Result<f64, String> {
    let v: f64 = token
        .parse()
        .map_err(|_| format!("{} is not a number", quoted(token)))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{} is not a finite number", quoted(token)))
    }
}
