//! The one byte encoding of values that cross ranks: little-endian numbers, length-prefixed
//! sequences and strings. A type that travels implements [`Wire`]; the typed collectives of
//! [`super::Comm`] encode and decode through it, so no caller invents a format of its own.
//!
//! Messages are produced by the same binary on every rank, so a message that does not decode is a
//! bug, not bad input: decoding panics (and the panic hook aborts every rank).

use std::path::PathBuf;

use crate::error::Error;

/// A value with a byte encoding for messages between ranks.
pub trait Wire: Sized {
    /// Appends the encoding of `self` to `out`.
    fn put(&self, out: &mut Vec<u8>);
    /// Reads one value from `r`.
    fn take(r: &mut Reader<'_>) -> Self;

    /// The value encoded in all of `bytes`.
    fn decode(bytes: &[u8]) -> Self {
        let mut r = Reader { bytes, at: 0 };
        let v = Self::take(&mut r);
        assert_eq!(r.at, bytes.len(), "message between ranks has trailing bytes");
        v
    }

    /// The encoding of `self`.
    fn encode(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.put(&mut out);
        out
    }
}

/// A cursor over a received message.
pub struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    /// The next `n` bytes.
    pub fn bytes(&mut self, n: usize) -> &[u8] {
        let s = self.bytes.get(self.at..self.at + n).expect("message between ranks is truncated");
        self.at += n;
        s
    }

    fn array<const N: usize>(&mut self) -> [u8; N] {
        self.bytes(N).try_into().expect("slice of N bytes")
    }
}

macro_rules! wire_number {
    ($($t:ty),*) => {$(
        impl Wire for $t {
            fn put(&self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes());
            }
            fn take(r: &mut Reader<'_>) -> Self {
                <$t>::from_le_bytes(r.array())
            }
        }
    )*};
}
wire_number!(u8, u32, u64, i64, f64);

impl Wire for usize {
    fn put(&self, out: &mut Vec<u8>) {
        (*self as u64).put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        u64::take(r) as usize
    }
}

impl Wire for bool {
    fn put(&self, out: &mut Vec<u8>) {
        u8::from(*self).put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        u8::take(r) != 0
    }
}

impl Wire for String {
    fn put(&self, out: &mut Vec<u8>) {
        self.len().put(out);
        out.extend_from_slice(self.as_bytes());
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let n = usize::take(r);
        String::from_utf8_lossy(r.bytes(n)).into_owned()
    }
}

impl Wire for PathBuf {
    fn put(&self, out: &mut Vec<u8>) {
        self.to_string_lossy().into_owned().put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        PathBuf::from(String::take(r))
    }
}

impl<T: Wire> Wire for Vec<T> {
    fn put(&self, out: &mut Vec<u8>) {
        self.len().put(out);
        for v in self {
            v.put(out);
        }
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let n = usize::take(r);
        (0..n).map(|_| T::take(r)).collect()
    }
}

impl<T: Wire, const N: usize> Wire for [T; N] {
    fn put(&self, out: &mut Vec<u8>) {
        for v in self {
            v.put(out);
        }
    }
    fn take(r: &mut Reader<'_>) -> Self {
        std::array::from_fn(|_| T::take(r))
    }
}

impl<T: Wire> Wire for Option<T> {
    fn put(&self, out: &mut Vec<u8>) {
        self.is_some().put(out);
        if let Some(v) = self {
            v.put(out);
        }
    }
    fn take(r: &mut Reader<'_>) -> Self {
        bool::take(r).then(|| T::take(r))
    }
}

impl<A: Wire, B: Wire> Wire for (A, B) {
    fn put(&self, out: &mut Vec<u8>) {
        self.0.put(out);
        self.1.put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        let a = A::take(r);
        (a, B::take(r))
    }
}

/// Errors travel whole, kind included, so that every rank can act on the kind of a failure that
/// happened elsewhere.
impl Wire for Error {
    fn put(&self, out: &mut Vec<u8>) {
        match self {
            Error::Input { path, location, reason } => {
                0u8.put(out);
                (path.clone(), (location.clone(), reason.clone())).put(out);
            }
            Error::Io { path, reason } => {
                1u8.put(out);
                (path.clone(), reason.clone()).put(out);
            }
            Error::Usage(m) => (2u8, m.clone()).put(out),
            Error::Numerical(m) => (3u8, m.clone()).put(out),
            Error::NotDefinite(m) => (4u8, m.clone()).put(out),
            Error::Hdf5 { path, reason } => {
                5u8.put(out);
                (path.clone(), reason.clone()).put(out);
            }
            Error::Memory(m) => (7u8, m.clone()).put(out),
            Error::Remote { rank, source } => {
                6u8.put(out);
                rank.put(out);
                source.put(out);
            }
        }
    }
    fn take(r: &mut Reader<'_>) -> Self {
        match u8::take(r) {
            0 => {
                let (path, (location, reason)) = Wire::take(r);
                Error::Input { path, location, reason }
            }
            1 => {
                let (path, reason) = Wire::take(r);
                Error::Io { path, reason }
            }
            2 => Error::Usage(String::take(r)),
            3 => Error::Numerical(String::take(r)),
            4 => Error::NotDefinite(String::take(r)),
            5 => {
                let (path, reason) = Wire::take(r);
                Error::Hdf5 { path, reason }
            }
            6 => {
                let rank = usize::take(r);
                Error::Remote { rank, source: Box::new(Error::take(r)) }
            }
            7 => Error::Memory(String::take(r)),
            tag => panic!("message between ranks: unknown error tag {tag}"),
        }
    }
}

impl<T: Wire> Wire for Box<T> {
    fn put(&self, out: &mut Vec<u8>) {
        (**self).put(out);
    }
    fn take(r: &mut Reader<'_>) -> Self {
        Box::new(T::take(r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip<T: Wire + PartialEq + std::fmt::Debug>(v: T) {
        assert_eq!(T::decode(&v.encode()), v);
    }

    #[test]
    fn values_round_trip() {
        round_trip(42u64);
        round_trip(-1.5e300f64);
        round_trip(String::from("ünïcode, commas"));
        round_trip(vec![[1.0f64, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        round_trip(Some((7usize, vec![1u32, 2])));
        round_trip(Option::<u8>::None);
    }

    #[test]
    fn errors_keep_their_kind() {
        for e in [
            Error::input("a.xyz", "line 3", "not a number"),
            Error::Io { path: "out".into(), reason: "disk full".into() },
            Error::Usage("bad".into()),
            Error::Numerical("singular".into()),
            Error::NotDefinite("pivot 3".into()),
            Error::hdf5("v.hdf", "closed"),
            Error::Memory("1 TB".into()),
            Error::Remote { rank: 2, source: Box::new(Error::NotDefinite("x".into())) },
        ] {
            let back = Error::decode(&e.encode());
            assert_eq!(back, e);
            assert_eq!(std::mem::discriminant(back.root()), std::mem::discriminant(e.root()));
        }
    }

    #[test]
    #[should_panic(expected = "truncated")]
    fn truncated_messages_are_caught() {
        let b = vec![1.0f64, 2.0].encode();
        Vec::<f64>::decode(&b[..b.len() - 1]);
    }
}
