//! Value parsers for the command line's options: clap's own parsers and
//! ranges decide what is accepted; these give a refused value one line that
//! names the option (taken from clap's argument, never repeated here) and
//! what it must be, negative values included (the options let them through
//! to the parser so the message is ours, not "unexpected argument").

use std::ffi::OsStr;
use std::marker::PhantomData;

use clap::builder::{RangedU64ValueParser, TypedValueParser};
use clap::error::ErrorKind;
use clap::{Arg, Command};

/// The value of an option as echoed in a message: cut to a readable length.
pub fn shown(value: &str) -> String {
    const SHOWN: usize = 40;
    if value.chars().count() <= SHOWN {
        value.to_string()
    } else {
        format!(
            "{}... ({} bytes)",
            value.chars().take(SHOWN).collect::<String>(),
            value.len()
        )
    }
}

/// `--name` of the argument being parsed.
fn flag(arg: Option<&Arg>) -> String {
    arg.and_then(Arg::get_long)
        .map_or_else(|| "the value".to_string(), |long| format!("--{long}"))
}

/// A refused value's one line.
fn refused(cmd: &Command, message: String) -> clap::Error {
    clap::Error::raw(ErrorKind::ValueValidation, message).with_cmd(cmd)
}

/// An integer option at least `min` and at most the type's largest value,
/// parsed by clap's ranged parser.
#[derive(Clone)]
pub struct Integer<T> {
    min: u64,
    kind: &'static str,
    value: PhantomData<fn() -> T>,
}

/// The largest value of an integer type, for messages.
pub trait Max {
    /// The largest value.
    const MAX: u64;
}

impl Max for u32 {
    const MAX: u64 = u32::MAX as u64;
}

impl Max for u64 {
    const MAX: u64 = u64::MAX;
}

impl Max for usize {
    const MAX: u64 = usize::MAX as u64;
}

impl<T> TypedValueParser for Integer<T>
where
    T: TryFrom<u64> + Max + Clone + Send + Sync + 'static,
    <T as TryFrom<u64>>::Error: std::error::Error + Send + Sync + 'static,
{
    type Value = T;

    fn parse_ref(&self, cmd: &Command, arg: Option<&Arg>, value: &OsStr) -> Result<T, clap::Error> {
        let text = value.to_string_lossy();
        let trimmed = OsStr::new(text.trim());
        RangedU64ValueParser::<T>::new()
            .range(self.min..=T::MAX)
            .parse_ref(cmd, arg, trimmed)
            .map_err(|_| {
                let flag = flag(arg);
                let whole = text.trim().parse::<i128>().ok();
                let message = match whole {
                    Some(v) if v >= i128::from(self.min) => {
                        format!("{flag} must be at most {}, not {}", T::MAX, shown(&text))
                    }
                    _ => format!("{flag} must be {}, not {}", self.kind, shown(&text)),
                };
                refused(cmd, message)
            })
    }
}

/// A positive integer option (1 or more).
pub fn positive<T>() -> Integer<T> {
    Integer {
        min: 1,
        kind: "a positive integer",
        value: PhantomData,
    }
}

/// A whole-number option (0 or more).
pub fn whole<T>() -> Integer<T> {
    Integer {
        min: 0,
        kind: "a whole number (0 or more)",
        value: PhantomData,
    }
}

/// A real option that must pass a check.
#[derive(Clone, Copy)]
pub struct Real {
    accepts: fn(f64) -> bool,
    must_be: &'static str,
}

impl TypedValueParser for Real {
    type Value = f64;

    fn parse_ref(
        &self,
        cmd: &Command,
        arg: Option<&Arg>,
        value: &OsStr,
    ) -> Result<f64, clap::Error> {
        let text = value.to_string_lossy();
        text.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| (self.accepts)(*v))
            .ok_or_else(|| {
                let message = format!(
                    "{} must be {}, not {}",
                    flag(arg),
                    self.must_be,
                    shown(&text)
                );
                refused(cmd, message)
            })
    }
}

/// A length option: a positive finite number of metres.
pub fn metres() -> Real {
    Real {
        accepts: |v| v.is_finite() && v > 0.0,
        must_be: "a positive number of metres",
    }
}

/// A fraction option in [0, 1).
pub fn fraction() -> Real {
    Real {
        accepts: |v| (0.0..1.0).contains(&v),
        must_be: "a fraction in [0, 1)",
    }
}

/// A positive finite real option.
pub fn positive_real() -> Real {
    Real {
        accepts: |v| v.is_finite() && v > 0.0,
        must_be: "a positive number",
    }
}

/// `--max-memory`'s value.
pub fn memory_size(text: &str) -> Result<u64, String> {
    radiosity::memory::parse_size(text).map_err(|m| format!("--max-memory: {m}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse<P: TypedValueParser>(
        parser: &P,
        long: &'static str,
        text: &str,
    ) -> Result<P::Value, String> {
        let mut cmd = Command::new("t").arg(Arg::new(long).long(long));
        cmd.build();
        let arg = cmd.get_arguments().next().unwrap();
        parser
            .parse_ref(&cmd, Some(arg), OsStr::new(text))
            .map_err(|e| e.to_string().lines().next().unwrap_or_default().to_string())
    }

    #[test]
    fn integers_name_the_option_and_what_it_must_be() {
        assert_eq!(parse(&positive::<u32>(), "n", " 7 "), Ok(7));
        assert_eq!(
            parse(&positive::<u32>(), "n", "0"),
            Err("error: --n must be a positive integer, not 0".into())
        );
        assert_eq!(
            parse(&positive::<u32>(), "n", "-3"),
            Err("error: --n must be a positive integer, not -3".into())
        );
        assert_eq!(
            parse(&positive::<u32>(), "n", "4294967296"),
            Err("error: --n must be at most 4294967295, not 4294967296".into())
        );
        assert_eq!(parse(&whole::<u64>(), "n", "0"), Ok(0));
        assert_eq!(
            parse(&whole::<u64>(), "n", "x"),
            Err("error: --n must be a whole number (0 or more), not x".into())
        );
    }

    #[test]
    fn reals_name_the_option_and_what_it_must_be() {
        assert_eq!(parse(&metres(), "size", "0.5"), Ok(0.5));
        assert_eq!(
            parse(&metres(), "size", "inf"),
            Err("error: --size must be a positive number of metres, not inf".into())
        );
        assert_eq!(parse(&fraction(), "f", "0"), Ok(0.0));
        let long = "1".repeat(50);
        assert_eq!(
            parse(&fraction(), "f", &long),
            Err(format!(
                "error: --f must be a fraction in [0, 1), not {}... (50 bytes)",
                "1".repeat(40)
            ))
        );
    }
}
