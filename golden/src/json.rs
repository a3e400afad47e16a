//! Strict JSON for the project's input documents (scene files, ledger
//! entries; SPEC.md section 15): one document and nothing after it, no key
//! twice in an object, and a struct only ever as a JSON object.
//!
//! serde's derive accepts a struct written as an array of its fields in
//! order, and serde_json keeps the last of two equal keys; both would read
//! a wrong file in silence. [`parse`] reads the text into a
//! [`serde_json::Value`] refusing duplicate keys (serde_json refuses
//! trailing input), and [`from_value`] deserializes a typed document from
//! it through [`Strict`], a deserializer that offers a struct only an
//! object and an array only to a list or a fixed-size array, naming the
//! JSON path of the element at fault.

use serde::de::{self, DeserializeSeed, IntoDeserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;
use serde_json::{Error, Map, Value};
use std::fmt;

/// Parses one JSON document; trailing input (a second document, garbage)
/// and a key given twice in one object are errors with line and column.
pub fn parse(text: &str) -> Result<Value, Error> {
    let UniqueKeys(v) = serde_json::from_str(text)?;
    Ok(v)
}

/// Deserializes `T` from `v` strictly; an error comes with the JSON path of
/// the element at fault (`objects[2].placement`, `.` for the document).
pub fn from_value<T: de::DeserializeOwned>(v: &Value) -> Result<T, (String, Error)> {
    serde_path_to_error::deserialize(Strict(v)).map_err(|e| {
        let path = e.path().to_string();
        (path, e.into_inner())
    })
}

/// A [`Value`] read with every object's keys distinct.
struct UniqueKeys(Value);

impl<'de> Deserialize<'de> for UniqueKeys {
    fn deserialize<D: de::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(UniqueVisitor).map(UniqueKeys)
    }
}

struct UniqueVisitor;

impl<'de> Visitor<'de> for UniqueVisitor {
    type Value = Value;
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, b: bool) -> Result<Value, E> {
        Ok(Value::Bool(b))
    }
    fn visit_i64<E>(self, n: i64) -> Result<Value, E> {
        Ok(n.into())
    }
    fn visit_u64<E>(self, n: u64) -> Result<Value, E> {
        Ok(n.into())
    }
    fn visit_f64<E>(self, n: f64) -> Result<Value, E> {
        Ok(serde_json::Number::from_f64(n).map_or(Value::Null, Value::Number))
    }
    fn visit_str<E>(self, s: &str) -> Result<Value, E> {
        Ok(Value::String(s.to_string()))
    }
    fn visit_string<E>(self, s: String) -> Result<Value, E> {
        Ok(Value::String(s))
    }
    fn visit_unit<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut out = Vec::new();
        while let Some(UniqueKeys(v)) = seq.next_element()? {
            out.push(v);
        }
        Ok(Value::Array(out))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut out = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            let UniqueKeys(v) = map.next_value()?;
            if out.insert(key.clone(), v).is_some() {
                return Err(de::Error::custom(format!(
                    "the key `{key}` twice in one object"
                )));
            }
        }
        Ok(Value::Object(out))
    }
}

/// A deserializer over a [`Value`] that gives a struct only an object.
#[derive(Clone, Copy)]
pub struct Strict<'a>(pub &'a Value);

fn unexpected(v: &Value) -> de::Unexpected<'_> {
    match v {
        Value::Null => de::Unexpected::Unit,
        Value::Bool(b) => de::Unexpected::Bool(*b),
        Value::Number(n) => match (n.as_u64(), n.as_i64()) {
            (Some(u), _) => de::Unexpected::Unsigned(u),
            (_, Some(i)) => de::Unexpected::Signed(i),
            _ => de::Unexpected::Float(n.as_f64().unwrap_or(f64::NAN)),
        },
        Value::String(s) => de::Unexpected::Str(s),
        Value::Array(_) => de::Unexpected::Seq,
        Value::Object(_) => de::Unexpected::Map,
    }
}

impl<'de, 'a> de::Deserializer<'de> for Strict<'a> {
    type Error = Error;

    /// Scalars as they are; an object as a map; an array is refused here,
    /// since only lists and fixed-size arrays (`deserialize_seq`,
    /// `deserialize_tuple`) may be written as one.
    fn deserialize_any<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        match self.0 {
            Value::Null => v.visit_unit(),
            Value::Bool(b) => v.visit_bool(*b),
            Value::Number(n) => match (n.as_u64(), n.as_i64(), n.as_f64()) {
                (Some(u), _, _) => v.visit_u64(u),
                (_, Some(i), _) => v.visit_i64(i),
                (_, _, Some(f)) => v.visit_f64(f),
                _ => Err(de::Error::custom("a number out of range")),
            },
            Value::String(s) => v.visit_str(s),
            Value::Array(_) => Err(de::Error::invalid_type(de::Unexpected::Seq, &v)),
            Value::Object(m) => v.visit_map(Fields::new(m)),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        match self.0 {
            Value::Null => v.visit_none(),
            _ => v.visit_some(self),
        }
    }

    fn deserialize_seq<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
        match self.0 {
            Value::Array(items) => v.visit_seq(Items(items.iter())),
            other => Err(de::Error::invalid_type(unexpected(other), &v)),
        }
    }

    fn deserialize_tuple<V: Visitor<'de>>(self, _len: usize, v: V) -> Result<V::Value, Error> {
        self.deserialize_seq(v)
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _fields: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Error> {
        match self.0 {
            Value::Object(m) => v.visit_map(Fields::new(m)),
            other => Err(de::Error::invalid_type(unexpected(other), &v)),
        }
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Error> {
        match self.0 {
            Value::String(s) => v.visit_enum(s.as_str().into_deserializer()),
            Value::Object(m) if m.len() == 1 => {
                let (k, inner) = m.iter().next().expect("one key");
                v.visit_enum(Variant(k, inner))
            }
            other => Err(de::Error::invalid_type(unexpected(other), &v)),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf unit unit_struct newtype_struct tuple_struct map
        identifier ignored_any
    }
}

struct Items<'a>(std::slice::Iter<'a, Value>);

impl<'de, 'a> SeqAccess<'de> for Items<'a> {
    type Error = Error;
    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Error> {
        self.0
            .next()
            .map(|v| seed.deserialize(Strict(v)))
            .transpose()
    }
}

struct Fields<'a> {
    iter: serde_json::map::Iter<'a>,
    value: Option<&'a Value>,
}

impl<'a> Fields<'a> {
    fn new(m: &'a Map<String, Value>) -> Self {
        Fields {
            iter: m.iter(),
            value: None,
        }
    }
}

impl<'de, 'a> MapAccess<'de> for Fields<'a> {
    type Error = Error;
    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Error> {
        match self.iter.next() {
            Some((k, v)) => {
                self.value = Some(v);
                seed.deserialize(k.as_str().into_deserializer()).map(Some)
            }
            None => Ok(None),
        }
    }
    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, Error> {
        let v = self
            .value
            .take()
            .ok_or_else(|| de::Error::custom("a value before its key"))?;
        seed.deserialize(Strict(v))
    }
}

struct Variant<'a>(&'a str, &'a Value);

impl<'de, 'a> de::EnumAccess<'de> for Variant<'a> {
    type Error = Error;
    type Variant = Strict<'a>;
    fn variant_seed<S: DeserializeSeed<'de>>(
        self,
        seed: S,
    ) -> Result<(S::Value, Strict<'a>), Error> {
        let tag = seed.deserialize(self.0.into_deserializer())?;
        Ok((tag, Strict(self.1)))
    }
}

impl<'de, 'a> de::VariantAccess<'de> for Strict<'a> {
    type Error = Error;
    fn unit_variant(self) -> Result<(), Error> {
        match self.0 {
            Value::Null => Ok(()),
            other => Err(de::Error::invalid_type(unexpected(other), &"null")),
        }
    }
    fn newtype_variant_seed<S: DeserializeSeed<'de>>(self, seed: S) -> Result<S::Value, Error> {
        seed.deserialize(self)
    }
    fn tuple_variant<V: Visitor<'de>>(self, _len: usize, v: V) -> Result<V::Value, Error> {
        de::Deserializer::deserialize_seq(self, v)
    }
    fn struct_variant<V: Visitor<'de>>(
        self,
        fields: &'static [&'static str],
        v: V,
    ) -> Result<V::Value, Error> {
        de::Deserializer::deserialize_struct(self, "", fields, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Inner {
        a: u8,
        b: [f32; 2],
    }

    #[derive(Debug, Deserialize, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Outer {
        inner: Inner,
        list: Vec<Inner>,
        #[serde(default)]
        maybe: Option<u32>,
    }

    fn read(text: &str) -> Result<Outer, String> {
        let v = parse(text).map_err(|e| format!(".: {e}"))?;
        from_value(&v).map_err(|(p, e)| format!("{p}: {e}"))
    }

    #[test]
    fn objects_read_as_before() {
        let o = read(r#"{"inner": {"a": 1, "b": [1, 2.5]}, "list": [], "maybe": 3}"#).unwrap();
        assert_eq!(o.inner.b, [1.0, 2.5]);
        assert_eq!(o.maybe, Some(3));
    }

    #[test]
    fn a_struct_as_an_array_is_refused_at_its_path() {
        let e = read(r#"{"inner": [1, [1, 2]], "list": []}"#).unwrap_err();
        assert!(e.starts_with("inner: invalid type: sequence"), "{e}");
        let e = read(r#"{"inner": {"a": 1, "b": [1, 2]}, "list": [[1, [1, 2]]]}"#).unwrap_err();
        assert!(e.starts_with("list[0]: invalid type: sequence"), "{e}");
        let e = read(r#"[{"a": 1, "b": [1, 2]}, []]"#).unwrap_err();
        assert!(e.starts_with(".: invalid type: sequence"), "{e}");
    }

    #[test]
    fn trailing_input_and_duplicate_keys_are_refused() {
        let ok = r#"{"inner": {"a": 1, "b": [1, 2]}, "list": []}"#;
        for bad in [format!("{ok} {ok}"), format!("{ok}x")] {
            let e = read(&bad).unwrap_err();
            assert!(e.contains("trailing characters"), "{e}");
        }
        let e = read(r#"{"inner": {"a": 1, "a": 2, "b": [1, 2]}, "list": []}"#).unwrap_err();
        assert!(
            e.contains("the key `a` twice") && e.contains("line 1"),
            "{e}"
        );
    }
}
