//! A fixed-capacity UTF-8 string that can live in shared memory.

use iceoryx2::prelude::ZeroCopySend;

/// A string longer than a [`FixedStr`] holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("{len} bytes, more than the {capacity} that fit")]
pub struct TooLong {
    /// Its length (bytes).
    pub len: usize,
    /// What fits (bytes).
    pub capacity: usize,
}

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

    /// Copy `s`, or refuse it if it is longer than `N` bytes: what must arrive whole
    /// (a job's path, an operator reply) is never cut.
    pub fn try_new(s: &str) -> Result<Self, TooLong> {
        if s.len() > N {
            return Err(TooLong {
                len: s.len(),
                capacity: N,
            });
        }
        let mut bytes = [0u8; N];
        bytes[..s.len()].copy_from_slice(s.as_bytes());
        Ok(FixedStr {
            len: s.len() as u32,
            bytes,
        })
    }

    /// Copy `s`; if longer than `N` bytes, cut at a character boundary and end with
    /// "…": for human-readable messages (alarms, notes), where the cut shows.
    pub fn truncated(s: &str) -> Self {
        match Self::try_new(s) {
            Ok(f) => f,
            Err(_) => {
                const MARK: &str = "…";
                let mut end = N.saturating_sub(MARK.len()).min(s.len());
                while !s.is_char_boundary(end) {
                    end -= 1;
                }
                let mut f = Self::empty();
                let _ = std::fmt::Write::write_str(&mut f, &s[..end]);
                let _ = std::fmt::Write::write_str(&mut f, MARK);
                f
            }
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
    fn what_does_not_fit_is_refused_or_cut_visibly() {
        assert_eq!(
            FixedStr::<4>::try_new("abcde").err(),
            Some(TooLong {
                len: 5,
                capacity: 4
            })
        );
        assert_eq!(FixedStr::<5>::try_new("abcde").unwrap().as_str(), "abcde");
        // a message: cut at a character boundary, the cut marked
        let s: FixedStr<7> = FixedStr::truncated("abé defg");
        assert_eq!(s.as_str(), "abé…");
        assert_eq!(FixedStr::<8>::truncated("x").as_str(), "x");
        assert!(!FixedStr::<4>::fits("abcde"));
    }

    #[test]
    fn formatting_appends_and_cuts_when_full() {
        use std::fmt::Write;
        let mut s: FixedStr<6> = FixedStr::try_new("ab").unwrap();
        let (n, tail) = (12, "xyz");
        write!(s, "{n}é{tail}").unwrap();
        assert_eq!(s.as_str(), "ab12é");
    }
}
