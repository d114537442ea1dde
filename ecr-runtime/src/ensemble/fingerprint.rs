//! The fingerprint of a run: what decides the rows of an ensemble's table, written at the top
//! of every table and part so that a resume ([`Control::resume`](super::Control::resume)) and
//! [`merge_parts`](super::merge_parts) can refuse rows of another run.
//!
//! # What it holds
//!
//! In this order (the order in which two fingerprints are compared, the first field that
//! differs being the one named):
//!
//! - `version`: the library's version (`ecr-runtime X.Y.Z`);
//! - the options: `method`, `rtol`, `atol`, `orders`, `max_step`, `max_steps`, `tstops`,
//!   `t_eval`, `dense`, `events` (their count: an event's function cannot be seen),
//!   `settings` (the stage solver's);
//! - `span` and `y0`: member 0's, as the member function makes it;
//! - `members`: the member count (in the table's first line);
//! - `columns`: the header row;
//! - `inputs`: the SHA-256 digest of every member's input cells as the table writes them
//!   (its parameters, its y₀: see [`Table::inputs`](super::Table::inputs));
//! - `key`: the user's own key ([`Table::key`](super::Table::key)), for what the library
//!   cannot see (the model's code, a data file it reads);
//! - `description`: the table's description (in the table's first line).
//!
//! A list of numbers (`tstops`, `t_eval`, `y0`) is written as it is up to eight values, and as
//! its length, first and last values and SHA-256 digest beyond.
//!
//! # In the file
//!
//! After the table's first line (`# ecr ensemble table of M members: DESCRIPTION`, or a part's
//! `# ecr ensemble part K/N of M members: DESCRIPTION`), one line `# NAME: VALUE` per field
//! (all but `members`, `columns` and `description`, which the first line and the header row
//! hold), then the header row.

use sha2::{Digest, Sha256};

/// The fields of the fingerprint that are not written as `# NAME: VALUE` lines: the table's
/// first line and its header row hold them.
const IMPLICIT: [&str; 3] = ["members", "columns", "description"];

/// The order of the last fields (see the module docs): fields of other names (the version and
/// the options) come first, in the order given.
const ORDER: [&str; 7] = [
    "span",
    "y0",
    "members",
    "columns",
    "inputs",
    "key",
    "description",
];

/// What decides the rows of a table (see the module docs): named fields, each a line of text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Fingerprint {
    fields: Vec<(String, String)>,
}

/// Where two fingerprints differ: the first field (in the order of the module docs) and its
/// value in each.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Difference {
    /// The field's name.
    pub field: String,
    /// Its value in the first fingerprint (`(none)` where it has no such field).
    pub first: String,
    /// Its value in the second.
    pub second: String,
}

impl Fingerprint {
    /// A fingerprint of the fields `(name, value)`, values made one line (line breaks become
    /// spaces).
    pub fn new<N: Into<String>, V: Into<String>>(fields: impl IntoIterator<Item = (N, V)>) -> Self {
        let mut fields: Vec<(String, String)> = fields
            .into_iter()
            .map(|(n, v)| (n.into(), one_line(&v.into())))
            .collect();
        let rank = |name: &str| ORDER.iter().position(|o| *o == name).map_or(0, |p| p + 1);
        fields.sort_by_key(|(n, _)| rank(n));
        Fingerprint { fields }
    }

    /// The fields, in order.
    pub fn fields(&self) -> &[(String, String)] {
        &self.fields
    }

    /// The value of field `name`.
    pub fn get(&self, name: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// The member count (field `members`), if it has one that is a number.
    pub fn members(&self) -> Option<usize> {
        self.get("members").and_then(|m| m.parse().ok())
    }

    /// The lines `# NAME: VALUE` written after a table's first line (every field but those the
    /// first line and the header hold), each with its line break.
    pub fn lines(&self) -> String {
        let mut out = String::new();
        for (name, value) in &self.fields {
            if IMPLICIT.contains(&name.as_str()) {
                continue;
            }
            if value.is_empty() {
                out += &format!("# {name}:\n");
            } else {
                out += &format!("# {name}: {value}\n");
            }
        }
        out
    }

    /// The field of a line `# NAME: VALUE` (without its line break), if it is one.
    pub(crate) fn parse_line(line: &str) -> Option<(String, String)> {
        let rest = line.strip_prefix("# ")?;
        let (name, value) = rest.split_once(':')?;
        let ok_name = !name.is_empty()
            && name
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_');
        if !ok_name {
            return None;
        }
        let value = value.strip_prefix(' ').unwrap_or(value);
        Some((name.to_string(), value.to_string()))
    }

    /// The first field (in order) whose value differs between `self` and `other`, if any.
    pub fn difference(&self, other: &Fingerprint) -> Option<Difference> {
        let none = || "(none)".to_string();
        let mut names: Vec<&str> = self.fields.iter().map(|(n, _)| n.as_str()).collect();
        for (n, _) in &other.fields {
            if !names.contains(&n.as_str()) {
                names.push(n);
            }
        }
        // Both in order: the names of `self`, then those only `other` has.
        for name in names {
            let (a, b) = (self.get(name), other.get(name));
            if a != b {
                return Some(Difference {
                    field: name.to_string(),
                    first: a.map_or_else(none, str::to_string),
                    second: b.map_or_else(none, str::to_string),
                });
            }
        }
        None
    }
}

/// Line breaks as spaces.
fn one_line(text: &str) -> String {
    text.replace(['\r', '\n'], " ")
}

/// A list of numbers as a fingerprint writes it: as it is (Rust's `{:?}` of each number) up to
/// eight values; beyond, its length, first and last values and the SHA-256 digest of every
/// value's bits.
pub fn numbers(values: &[f64]) -> String {
    if values.len() <= 8 {
        return format!("{values:?}");
    }
    let mut h = Sha256::new();
    for v in values {
        h.update(v.to_bits().to_le_bytes());
    }
    format!(
        "{} values from {:?} to {:?}, sha256 {}",
        values.len(),
        values[0],
        values[values.len() - 1],
        hex(&h.finalize())
    )
}

/// Lowercase hex.
pub(crate) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_ordered_written_parsed_and_compared() {
        let a = Fingerprint::new([
            ("description", "d"),
            ("key", ""),
            ("members", "4"),
            ("version", "v"),
            ("rtol", "1e-6"),
            ("span", "(0.0, 1.0)"),
        ]);
        let names: Vec<&str> = a.fields().iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            ["version", "rtol", "span", "members", "key", "description"]
        );
        assert_eq!(
            a.lines(),
            "# version: v\n# rtol: 1e-6\n# span: (0.0, 1.0)\n# key:\n"
        );
        for line in a.lines().lines() {
            let (n, v) = Fingerprint::parse_line(line).unwrap();
            assert_eq!(a.get(&n), Some(v.as_str()));
        }
        assert_eq!(Fingerprint::parse_line("member,status"), None);
        assert_eq!(a.members(), Some(4));
        let mut fields = a.fields().to_vec();
        fields[1].1 = "1e-3".into();
        fields[5].1 = "e".into();
        let b = Fingerprint::new(fields);
        let d = a.difference(&b).unwrap();
        assert_eq!((d.field.as_str(), d.first.as_str()), ("rtol", "1e-6"));
        assert_eq!(d.second, "1e-3");
        assert_eq!(a.difference(&a.clone()), None);
        assert!(numbers(&[1.0, 2.0]) == "[1.0, 2.0]");
        assert!(numbers(&[0.5; 9]).starts_with("9 values from 0.5 to 0.5, sha256 "));
    }
}
