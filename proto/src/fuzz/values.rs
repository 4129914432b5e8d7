//! Values of any serde type drawn from entropy bytes, through the type's own
//! `Deserialize` impl: every wire message (and every type nested in one) gets
//! random values without a hand-written generator, and a field added later
//! is fuzzed too.
//!
//! Numbers favour the extremes that break arithmetic (`i64::MIN`/`MAX`, 0,
//! NaN, ±inf, `f64::MAX`, subnormals) over uniform bits; strings favour the
//! site's ids (`c1`, `r1`, ...) so that cores are reached past their id
//! checks; sequences are mostly short and sometimes huge.

use serde::de::{
    self, DeserializeOwned, DeserializeSeed, EnumAccess, Expected, IntoDeserializer, MapAccess,
    SeqAccess, VariantAccess, Visitor,
};

/// Ids and names the built-in sites use, so that drawn strings hit real entries.
const WORDS: [&str; 12] = [
    "c1",
    "c2",
    "c3",
    "c4",
    "r1",
    "r2",
    "r3",
    "lab",
    "warehouse",
    "a",
    "",
    "x",
];

/// The longest sequence drawn (a "huge vector": most are 0-7 long).
pub const HUGE_LEN: usize = 4_096;

/// Draws a `T` from `entropy` (bytes past its end read as zeros, so every
/// draw completes). `None` only when `T`'s own validation refuses the value.
pub fn draw<T: DeserializeOwned>(entropy: &[u8]) -> Option<T> {
    let mut source = Source {
        bytes: entropy,
        depth: 0,
    };
    T::deserialize(&mut source).ok()
}

/// The entropy reader and the deserializer.
struct Source<'a> {
    bytes: &'a [u8],
    depth: u32,
}

/// The generator's only error: the drawn value was refused by the type.
#[derive(Debug)]
struct Refused(String);

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Refused {}

impl de::Error for Refused {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        Refused(msg.to_string())
    }
}

impl Source<'_> {
    fn byte(&mut self) -> u8 {
        match self.bytes.split_first() {
            Some((b, rest)) => {
                self.bytes = rest;
                *b
            }
            None => 0,
        }
    }

    fn raw_u64(&mut self) -> u64 {
        let mut v = 0u64;
        for _ in 0..8 {
            v = (v << 8) | u64::from(self.byte());
        }
        v
    }

    /// An integer: an extreme one time in four, small one time in four.
    fn int(&mut self, min: i128, max: i128) -> i128 {
        let class = self.byte();
        let v = match class % 8 {
            0 => min,
            1 => max,
            2 => 0,
            3 => i128::from(self.byte() % 16),
            4 => max - i128::from(self.byte() % 4),
            _ => i128::from(self.raw_u64() as i64),
        };
        if v < min || v > max {
            min + v.rem_euclid(max - min + 1)
        } else {
            v
        }
    }

    fn float(&mut self) -> f64 {
        match self.byte() % 12 {
            0 => f64::NAN,
            1 => f64::INFINITY,
            2 => f64::NEG_INFINITY,
            3 => f64::MAX,
            4 => f64::MIN_POSITIVE / 2.0,
            5 => 0.0,
            6 => -f64::MAX,
            7 => f64::from_bits(self.raw_u64()),
            // Plausible site-sized numbers.
            _ => f64::from(self.raw_u64() as i32 as i16) / 100.0,
        }
    }

    fn len(&mut self) -> usize {
        match self.byte() {
            0..=239 => usize::from(self.byte() % 8),
            240..=253 => usize::from(self.byte() % 64),
            _ => HUGE_LEN,
        }
    }

    fn string(&mut self) -> String {
        let b = self.byte();
        if b < 192 {
            return WORDS[usize::from(b) % WORDS.len()].to_string();
        }
        let n = self.len();
        (0..n)
            .map(|_| match self.byte() {
                0..=199 => char::from(b'a' + self.byte() % 26),
                b => char::from_u32(u32::from(b) * 911).unwrap_or('\u{fffd}'),
            })
            .collect()
    }
}

macro_rules! ints {
    ($($method:ident $visit:ident $t:ty),*) => {$(
        fn $method<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
            let x = self.int(i128::from(<$t>::MIN), i128::from(<$t>::MAX));
            v.$visit(x as $t)
        }
    )*};
}

impl<'de> de::Deserializer<'de> for &mut Source<'_> {
    type Error = Refused;

    fn deserialize_any<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        self.deserialize_u64(v)
    }

    ints!(deserialize_i8 visit_i8 i8, deserialize_i16 visit_i16 i16,
          deserialize_i32 visit_i32 i32, deserialize_i64 visit_i64 i64,
          deserialize_u8 visit_u8 u8, deserialize_u16 visit_u16 u16,
          deserialize_u32 visit_u32 u32, deserialize_u64 visit_u64 u64);

    fn deserialize_bool<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_bool(self.byte() & 1 == 1)
    }
    fn deserialize_f32<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_f32(self.float() as f32)
    }
    fn deserialize_f64<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_f64(self.float())
    }
    fn deserialize_char<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_char(char::from(b'a' + self.byte() % 26))
    }
    fn deserialize_str<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_string(self.string())
    }
    fn deserialize_string<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_string(self.string())
    }
    fn deserialize_bytes<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        let n = self.len();
        let bytes: Vec<u8> = (0..n).map(|_| self.byte()).collect();
        v.visit_byte_buf(bytes)
    }
    fn deserialize_byte_buf<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        self.deserialize_bytes(v)
    }
    fn deserialize_option<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        if self.byte() & 1 == 0 {
            v.visit_none()
        } else {
            v.visit_some(self)
        }
    }
    fn deserialize_unit<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_unit()
    }
    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        v: V,
    ) -> Result<V::Value, Refused> {
        v.visit_unit()
    }
    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        v: V,
    ) -> Result<V::Value, Refused> {
        v.visit_newtype_struct(self)
    }
    fn deserialize_seq<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        // A CDR string is read as a sequence of bytes by `wire_string`; its
        // visitor takes a plain string too, which is the one worth drawing.
        if format!("{}", &v as &dyn Expected).contains("NUL-terminated") {
            return v.visit_string(self.string());
        }
        let n = if self.depth > 3 { 0 } else { self.len() };
        self.depth += 1;
        let r = v.visit_seq(Elements { src: self, left: n });
        self.depth -= 1;
        r
    }
    fn deserialize_tuple<V: Visitor<'de>>(self, len: usize, v: V) -> Result<V::Value, Refused> {
        v.visit_seq(Elements {
            src: self,
            left: len,
        })
    }
    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        len: usize,
        v: V,
    ) -> Result<V::Value, Refused> {
        self.deserialize_tuple(len, v)
    }
    fn deserialize_map<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        let n = if self.depth > 3 { 0 } else { self.len() };
        self.depth += 1;
        let r = v.visit_map(Elements { src: self, left: n });
        self.depth -= 1;
        r
    }
    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _: &'static str,
        fields: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Refused> {
        self.deserialize_tuple(fields.len(), v)
    }
    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _: &'static str,
        variants: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Refused> {
        let index = usize::from(self.byte()) % variants.len().max(1);
        v.visit_enum(Variant {
            src: self,
            index: index as u32,
        })
    }
    fn deserialize_identifier<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        self.deserialize_str(v)
    }
    fn deserialize_ignored_any<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Refused> {
        v.visit_unit()
    }
}

struct Elements<'s, 'a> {
    src: &'s mut Source<'a>,
    left: usize,
}

impl<'de> SeqAccess<'de> for Elements<'_, '_> {
    type Error = Refused;
    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Refused> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        seed.deserialize(&mut *self.src).map(Some)
    }
    fn size_hint(&self) -> Option<usize> {
        Some(self.left)
    }
}

impl<'de> MapAccess<'de> for Elements<'_, '_> {
    type Error = Refused;
    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Refused> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        seed.deserialize(&mut *self.src).map(Some)
    }
    fn next_value_seed<T: DeserializeSeed<'de>>(&mut self, seed: T) -> Result<T::Value, Refused> {
        seed.deserialize(&mut *self.src)
    }
}

struct Variant<'s, 'a> {
    src: &'s mut Source<'a>,
    index: u32,
}

impl<'de, 's, 'a> EnumAccess<'de> for Variant<'s, 'a> {
    type Error = Refused;
    type Variant = Self;
    fn variant_seed<T: DeserializeSeed<'de>>(self, seed: T) -> Result<(T::Value, Self), Refused> {
        let index: de::value::U32Deserializer<Refused> = self.index.into_deserializer();
        Ok((seed.deserialize(index)?, self))
    }
}

impl<'de> VariantAccess<'de> for Variant<'_, '_> {
    type Error = Refused;
    fn unit_variant(self) -> Result<(), Refused> {
        Ok(())
    }
    fn newtype_variant_seed<T: DeserializeSeed<'de>>(self, seed: T) -> Result<T::Value, Refused> {
        seed.deserialize(&mut *self.src)
    }
    fn tuple_variant<V: Visitor<'de>>(self, len: usize, v: V) -> Result<V::Value, Refused> {
        de::Deserializer::deserialize_tuple(&mut *self.src, len, v)
    }
    fn struct_variant<V: Visitor<'de>>(
        self,
        fields: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Refused> {
        de::Deserializer::deserialize_tuple(&mut *self.src, fields.len(), v)
    }
}
