//! `[build] memory` and `chunkc build --memory`: how much memory a build may keep its values in,
//! written with a unit (`"512MiB"`, `"2 GiB"`, `"1.5GB"`).

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A size in bytes, written with a unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemorySize(pub u64);

/// The units a size may be written in, longest first (`MiB` before `M`).
const UNITS: &[(&str, u64)] = &[
    ("KiB", 1 << 10),
    ("MiB", 1 << 20),
    ("GiB", 1 << 30),
    ("TiB", 1 << 40),
    ("KB", 1_000),
    ("MB", 1_000_000),
    ("GB", 1_000_000_000),
    ("TB", 1_000_000_000_000),
    ("K", 1 << 10),
    ("M", 1 << 20),
    ("G", 1 << 30),
    ("T", 1 << 40),
    ("B", 1),
];

impl std::str::FromStr for MemorySize {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let t = text.trim();
        let unit = UNITS
            .iter()
            .find(|(u, _)| t.len() > u.len() && t[t.len() - u.len()..].eq_ignore_ascii_case(u));
        let Some(&(name, scale)) = unit else {
            return Err(format!(
                "`{text}` has no unit: write a size such as \"512MiB\", \"2GiB\" or \"1.5GB\""
            ));
        };
        let number = t[..t.len() - name.len()].trim();
        match number.parse::<f64>() {
            Ok(n) if n.is_finite() && n > 0.0 => Ok(MemorySize((n * scale as f64) as u64)),
            _ => Err(format!("`{text}`: `{number}` is not a positive number")),
        }
    }
}

impl std::fmt::Display for MemorySize {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let (mib, gib) = (
            self.0 as f64 / (1u64 << 20) as f64,
            self.0 as f64 / (1u64 << 30) as f64,
        );
        match gib >= 1.0 {
            true => write!(f, "{gib:.1} GiB"),
            false => write!(f, "{mib:.0} MiB"),
        }
    }
}

impl Serialize for MemorySize {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&format!("{}B", self.0))
    }
}

impl<'de> Deserialize<'de> for MemorySize {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_with_their_units() {
        let size = |t: &str| t.parse::<MemorySize>().map(|m| m.0);
        assert_eq!(size("512MiB"), Ok(512 << 20));
        assert_eq!(size("2 GiB"), Ok(2 << 30));
        assert_eq!(size("1.5GB"), Ok(1_500_000_000));
        assert_eq!(size("800m"), Ok(800 << 20));
        assert_eq!(size("4096B"), Ok(4096));
        assert!(size("2").unwrap_err().contains("no unit"));
        assert!(size("-1GiB").unwrap_err().contains("not a positive number"));
        assert!(size("lots GiB").is_err());
    }
}
