//! A CDR string decoder that never allocates more than the payload holds.
//!
//! The `cdr` crate reads a string by allocating its declared length before
//! checking that the bytes exist, so a 4 GiB length prefix would allocate
//! 4 GiB. On the wire a CDR string is a `u32` length (including the NUL), the
//! bytes and a NUL: exactly a CDR sequence of `u8`. Decoding it as a sequence
//! reads byte by byte, and serde pre-allocates only a cautious bounded amount,
//! so memory grows with the bytes actually present.

use serde::de::{Deserializer, Error, SeqAccess, Visitor};

/// `#[serde(deserialize_with = "crate::wire_string::deserialize")]` for `String` fields.
pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    d.deserialize_seq(CdrStringVisitor)
}

/// The same for `Vec<String>` fields.
pub(crate) fn deserialize_vec<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<String>, D::Error> {
    struct Many;
    impl<'de> Visitor<'de> for Many {
        type Value = Vec<String>;
        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a sequence of CDR strings")
        }
        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
            let mut out = Vec::new();
            while let Some(s) = seq.next_element::<Wrapped>()? {
                out.push(s.0);
            }
            Ok(out)
        }
    }
    struct Wrapped(String);
    impl<'de> serde::Deserialize<'de> for Wrapped {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            deserialize(d).map(Wrapped)
        }
    }
    d.deserialize_seq(Many)
}

struct CdrStringVisitor;

impl<'de> Visitor<'de> for CdrStringVisitor {
    type Value = String;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a NUL-terminated CDR string")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<String, A::Error> {
        let mut bytes: Vec<u8> = Vec::new();
        while let Some(b) = seq.next_element::<u8>()? {
            bytes.push(b);
        }
        match bytes.pop() {
            Some(0) => {}
            _ => return Err(A::Error::custom("CDR string without its terminating NUL")),
        }
        if bytes.contains(&0) {
            return Err(A::Error::custom("CDR string with a NUL inside"));
        }
        String::from_utf8(bytes).map_err(|e| A::Error::custom(format!("invalid UTF-8: {e}")))
    }

    // Self-describing formats (JSON in tests and tools) hand over a plain string.
    fn visit_str<E: Error>(self, v: &str) -> Result<String, E> {
        Ok(v.to_string())
    }
}
