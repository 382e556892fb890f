//! Memory sizes as people write and read them (beyond the paper):
//! `--max-memory 24G`, and `1.5 GiB` in messages.

/// `1.5 GiB`, `300 MiB`, `12 KiB`.
#[must_use]
pub fn bytes(n: u64) -> String {
    let n = n as f64;
    if n >= (1u64 << 30) as f64 {
        format!("{:.1} GiB", n / (1u64 << 30) as f64)
    } else if n >= (1u64 << 20) as f64 {
        format!("{:.0} MiB", n / (1u64 << 20) as f64)
    } else {
        format!("{:.0} KiB", n / 1024.0)
    }
}

/// Parses a memory size: a number with an optional unit, `K`, `M`, `G` or
/// `T` (powers of 1024, optionally followed by `iB` or `B`); a bare number
/// is MiB, as `--max-file-size` takes it. `24G`, `1.5GiB`, `512`.
pub fn parse_size(text: &str) -> Result<u64, SizeError> {
    let t = text.trim();
    let split = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| SizeError::NotASize(text.to_string()))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "m" | "mb" | "mib" => 20,
        "k" | "kb" | "kib" => 10,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        "b" => 0,
        _ => {
            return Err(SizeError::UnknownUnit {
                text: text.to_string(),
                unit: unit.to_string(),
            });
        }
    };
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && (1.0..1e19).contains(&bytes)) {
        return Err(SizeError::NotPositive(text.to_string()));
    }
    Ok(bytes as u64)
}

/// A memory size [`parse_size`] cannot read.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SizeError {
    /// No number where the size should start.
    #[error("'{0}' is not a size such as 512M, 24G or 1.5GiB")]
    NotASize(String),
    /// A unit other than K, M, G or T.
    #[error("'{text}': unknown unit '{unit}' (use K, M, G or T)")]
    UnknownUnit {
        /// The size as given.
        text: String,
        /// Its unit.
        unit: String,
    },
    /// Zero, negative or too large.
    #[error("'{0}' is not a positive size")]
    NotPositive(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("512"), Ok(512 << 20));
        assert_eq!(parse_size("24G"), Ok(24 << 30));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("100 kB"), Ok(100 << 10));
        assert!(parse_size("-1G").is_err());
        assert!(parse_size("lots").is_err());
        assert!(
            parse_size("3X")
                .unwrap_err()
                .to_string()
                .contains("unknown unit")
        );
    }
}
