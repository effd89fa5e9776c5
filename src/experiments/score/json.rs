//! JSON summaries of `limot eval`: an ordered tree ([`Json`]) written with
//! serde_json, pretty-printed with two-space indentation.
//!
//! The tree keeps the order its fields were built in. Numbers are written in
//! Rust's `Display` form (the shortest round-trip digits without exponent:
//! `1` for 1.0, `0.1` for 0.1) rather than serde_json's default (`1.0`, `1e-7`),
//! and control characters other than `\n`, `\r`, `\t` as `\u00xx`.

use serde::ser::{SerializeMap, SerializeSeq};
use serde_json::ser::{CharEscape, Formatter, PrettyFormatter};
use std::io;

/// A JSON value. Non-finite numbers are written as `null` (JSON has no NaN).
#[derive(Debug, Clone, PartialEq)]
pub enum Json {
    Null,
    Bool(bool),
    Num(f64),
    Int(i64),
    Str(String),
    Arr(Vec<Json>),
    Obj(Vec<(String, Json)>),
}

impl From<f64> for Json {
    fn from(v: f64) -> Json {
        Json::Num(v)
    }
}

impl From<Option<f64>> for Json {
    fn from(v: Option<f64>) -> Json {
        v.map_or(Json::Null, Json::Num)
    }
}

impl From<usize> for Json {
    fn from(v: usize) -> Json {
        Json::Int(i64::try_from(v).unwrap_or(i64::MAX))
    }
}

impl From<u64> for Json {
    fn from(v: u64) -> Json {
        Json::Int(i64::try_from(v).unwrap_or(i64::MAX))
    }
}

impl From<bool> for Json {
    fn from(v: bool) -> Json {
        Json::Bool(v)
    }
}

impl From<&str> for Json {
    fn from(v: &str) -> Json {
        Json::Str(v.to_string())
    }
}

impl From<String> for Json {
    fn from(v: String) -> Json {
        Json::Str(v)
    }
}

/// Builds an object from `(key, value)` pairs, keeping their order.
pub fn obj<const N: usize>(pairs: [(&str, Json); N]) -> Json {
    Json::Obj(pairs.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
}

impl serde::Serialize for Json {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Json::Null => s.serialize_unit(),
            Json::Bool(b) => s.serialize_bool(*b),
            Json::Num(v) if v.is_finite() => s.serialize_f64(*v),
            Json::Num(_) => s.serialize_unit(),
            Json::Int(v) => s.serialize_i64(*v),
            Json::Str(text) => s.serialize_str(text),
            Json::Arr(items) => {
                let mut seq = s.serialize_seq(Some(items.len()))?;
                for item in items {
                    seq.serialize_element(item)?;
                }
                seq.end()
            }
            Json::Obj(fields) => {
                let mut map = s.serialize_map(Some(fields.len()))?;
                for (key, value) in fields {
                    map.serialize_entry(key, value)?;
                }
                map.end()
            }
        }
    }
}

/// serde_json's pretty formatter with `Display` numbers and `\u00xx` for
/// every control character but `\n`, `\r` and `\t` (module docs).
struct SummaryFormatter(PrettyFormatter<'static>);

impl Formatter for SummaryFormatter {
    fn write_f64<W: ?Sized + io::Write>(&mut self, w: &mut W, value: f64) -> io::Result<()> {
        write!(w, "{value}")
    }

    fn write_char_escape<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        escape: CharEscape,
    ) -> io::Result<()> {
        match escape {
            CharEscape::Backspace => w.write_all(b"\\u0008"),
            CharEscape::FormFeed => w.write_all(b"\\u000c"),
            other => self.0.write_char_escape(w, other),
        }
    }

    fn begin_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.0.begin_array(w)
    }

    fn end_array<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.0.end_array(w)
    }

    fn begin_array_value<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> io::Result<()> {
        self.0.begin_array_value(w, first)
    }

    fn end_array_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.0.end_array_value(w)
    }

    fn begin_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.0.begin_object(w)
    }

    fn end_object<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.0.end_object(w)
    }

    fn begin_object_key<W: ?Sized + io::Write>(
        &mut self,
        w: &mut W,
        first: bool,
    ) -> io::Result<()> {
        self.0.begin_object_key(w, first)
    }

    fn begin_object_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.0.begin_object_value(w)
    }

    fn end_object_value<W: ?Sized + io::Write>(&mut self, w: &mut W) -> io::Result<()> {
        self.0.end_object_value(w)
    }
}

impl Json {
    /// Pretty-printed with two-space indentation and a final newline.
    pub fn render(&self) -> String {
        let mut out = Vec::new();
        let mut ser = serde_json::Serializer::with_formatter(
            &mut out,
            SummaryFormatter(PrettyFormatter::new()),
        );
        serde::Serialize::serialize(self, &mut ser).expect("writing JSON to memory cannot fail");
        let mut text = String::from_utf8(out).expect("serde_json writes UTF-8");
        text.push('\n');
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_nested_values_and_escapes() {
        let v = obj([
            ("a", Json::Num(0.1)),
            ("nan", Json::Num(f64::NAN)),
            ("s", Json::from("q\"\\\n")),
            (
                "list",
                Json::Arr(vec![Json::Int(1), Json::Null, Json::Bool(true)]),
            ),
            ("empty", Json::Obj(vec![])),
        ]);
        let text = v.render();
        assert_eq!(
            text,
            "{\n  \"a\": 0.1,\n  \"nan\": null,\n  \"s\": \"q\\\"\\\\\\n\",\n  \"list\": [\n    1,\n    null,\n    true\n  ],\n  \"empty\": {}\n}\n"
        );
    }

    /// The hand-written renderer this module used before serde_json, kept as
    /// the reference the serde_json output must match byte for byte.
    fn reference(v: &Json, out: &mut String, indent: usize) {
        use std::fmt::Write as _;
        fn escape(s: &str, out: &mut String) {
            out.push('"');
            for ch in s.chars() {
                match ch {
                    '"' => out.push_str("\\\""),
                    '\\' => out.push_str("\\\\"),
                    '\n' => out.push_str("\\n"),
                    '\r' => out.push_str("\\r"),
                    '\t' => out.push_str("\\t"),
                    c if (c as u32) < 0x20 => {
                        let _ = write!(out, "\\u{:04x}", c as u32);
                    }
                    c => out.push(c),
                }
            }
            out.push('"');
        }
        let pad = |out: &mut String, n: usize| out.push_str(&"  ".repeat(n));
        match v {
            Json::Null => out.push_str("null"),
            Json::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
            Json::Num(x) if x.is_finite() => {
                let _ = write!(out, "{x}");
            }
            Json::Num(_) => out.push_str("null"),
            Json::Int(x) => {
                let _ = write!(out, "{x}");
            }
            Json::Str(s) => escape(s, out),
            Json::Arr(items) if items.is_empty() => out.push_str("[]"),
            Json::Arr(items) => {
                out.push_str("[\n");
                for (i, item) in items.iter().enumerate() {
                    pad(out, indent + 1);
                    reference(item, out, indent + 1);
                    out.push_str(if i + 1 < items.len() { ",\n" } else { "\n" });
                }
                pad(out, indent);
                out.push(']');
            }
            Json::Obj(fields) if fields.is_empty() => out.push_str("{}"),
            Json::Obj(fields) => {
                out.push_str("{\n");
                for (i, (key, value)) in fields.iter().enumerate() {
                    pad(out, indent + 1);
                    escape(key, out);
                    out.push_str(": ");
                    reference(value, out, indent + 1);
                    out.push_str(if i + 1 < fields.len() { ",\n" } else { "\n" });
                }
                pad(out, indent);
                out.push('}');
            }
        }
    }

    #[test]
    fn serde_json_output_matches_the_hand_written_reference() {
        // splitmix64 bit patterns: every kind of finite f64, plus edge values.
        let mut state = 0x1234_5678_9abc_def0_u64;
        let mut next = move || {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        };
        let mut nums: Vec<Json> = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            1e-7,
            1e21,
            1e300,
            5e-324,
            f64::MAX,
            f64::MIN_POSITIVE,
            f64::NAN,
            f64::INFINITY,
            123456.789,
            2.5e-3,
        ]
        .into_iter()
        .map(Json::Num)
        .collect();
        for _ in 0..2000 {
            nums.push(Json::Num(f64::from_bits(next())));
            nums.push(Json::Num((next() as f64 / u64::MAX as f64 - 0.5) * 200.0));
        }
        nums.extend([Json::Int(i64::MIN), Json::Int(i64::MAX), Json::Int(0)]);
        let all_chars: String = (0u8..0x80).map(char::from).chain("é→😀".chars()).collect();
        let v = Json::Obj(vec![
            ("nums".into(), Json::Arr(nums)),
            (all_chars.clone(), Json::Str(all_chars)),
            ("empty_arr".into(), Json::Arr(vec![])),
            ("empty_obj".into(), Json::Obj(vec![])),
            (
                "nested".into(),
                Json::Arr(vec![
                    obj([("a", Json::Arr(vec![Json::Obj(vec![])]))]),
                    Json::Null,
                ]),
            ),
            (
                "bools".into(),
                Json::Arr(vec![Json::Bool(true), Json::Bool(false)]),
            ),
        ]);
        let mut expected = String::new();
        reference(&v, &mut expected, 0);
        expected.push('\n');
        assert_eq!(v.render(), expected);
    }
}
