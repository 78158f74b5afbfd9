//! A fixed-capacity UTF-8 string that can live in shared memory.

use iceoryx2::prelude::ZeroCopySend;

/// Up to `N` bytes of UTF-8, stored inline.
#[derive(Clone, Copy, ZeroCopySend)]
#[repr(C)]
pub struct FixedStr<const N: usize> {
    len: u32,
    bytes: [u8; N],
}

impl<const N: usize> FixedStr<N> {
    /// The empty string.
    pub const fn empty() -> Self {
        FixedStr {
            len: 0,
            bytes: [0; N],
        }
    }

    /// Copy `s`, cut at a character boundary if longer than `N` bytes.
    pub fn new(s: &str) -> Self {
        let mut end = s.len().min(N);
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        let mut bytes = [0u8; N];
        bytes[..end].copy_from_slice(&s.as_bytes()[..end]);
        FixedStr {
            len: end as u32,
            bytes,
        }
    }

    /// The text (empty if the bytes are not valid UTF-8, which `new` never produces).
    pub fn as_str(&self) -> &str {
        let len = (self.len as usize).min(N);
        std::str::from_utf8(&self.bytes[..len]).unwrap_or("")
    }

    /// True if `s` did not fit whole.
    pub fn fits(s: &str) -> bool {
        s.len() <= N
    }
}

/// Appends, cut at a character boundary when full: formatting into a `FixedStr`
/// allocates nothing (messages raised on the cycle path).
impl<const N: usize> std::fmt::Write for FixedStr<N> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        let len = (self.len as usize).min(N);
        let mut end = s.len().min(N - len);
        while !s.is_char_boundary(end) {
            end -= 1;
        }
        self.bytes[len..len + end].copy_from_slice(&s.as_bytes()[..end]);
        self.len = (len + end) as u32;
        Ok(())
    }
}

impl<const N: usize> Default for FixedStr<N> {
    fn default() -> Self {
        Self::empty()
    }
}

impl<const N: usize> std::fmt::Debug for FixedStr<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:?}", self.as_str())
    }
}

impl<const N: usize> PartialEq for FixedStr<N> {
    fn eq(&self, other: &Self) -> bool {
        self.as_str() == other.as_str()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cuts_at_char_boundary() {
        let s: FixedStr<4> = FixedStr::new("abé d");
        assert_eq!(s.as_str(), "abé");
        assert!(!FixedStr::<4>::fits("abcde"));
        assert_eq!(FixedStr::<8>::new("x").as_str(), "x");
    }

    #[test]
    fn formatting_appends_and_cuts_when_full() {
        use std::fmt::Write;
        let mut s: FixedStr<6> = FixedStr::new("ab");
        let (n, tail) = (12, "xyz");
        write!(s, "{n}é{tail}").unwrap();
        assert_eq!(s.as_str(), "ab12é");
    }
}
