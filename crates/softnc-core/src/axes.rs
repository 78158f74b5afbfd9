//! One axis type for the whole stack: [`Axis`] names an axis by LinuxCNC's nine
//! letters, [`Axes<T>`] holds one `T` for each of the [`MAX_AXES`] axes the stack
//! carries (the profile, the servo boundary, the position cycle, the learning store,
//! the messages). Raising [`MAX_AXES`] (up to nine) is the one change that gives the
//! stack more axes; nothing else counts them.

use crate::MAX_AXES;
use serde::{Deserialize, Serialize};
use std::ops::{Deref, DerefMut, Index, IndexMut};

/// An axis, by LinuxCNC's letters (its `[TRAJ]COORDINATES`): X Y Z, the rotary A B
/// C, the secondary linear U V W.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Axis {
    /// X.
    X = 0,
    /// Y.
    Y,
    /// Z.
    Z,
    /// A (rotary about X).
    A,
    /// B (rotary about Y).
    B,
    /// C (rotary about Z).
    C,
    /// U (parallel to X).
    U,
    /// V (parallel to Y).
    V,
    /// W (parallel to Z).
    W,
}

/// The nine axes LinuxCNC knows, in its order.
pub const ALL_AXES: [Axis; 9] = [
    Axis::X,
    Axis::Y,
    Axis::Z,
    Axis::A,
    Axis::B,
    Axis::C,
    Axis::U,
    Axis::V,
    Axis::W,
];

const _: () = assert!(MAX_AXES >= 1 && MAX_AXES <= ALL_AXES.len());

impl Axis {
    /// Its index in an [`Axes`] (X = 0).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The axis at index `i` of [`ALL_AXES`].
    pub fn from_index(i: usize) -> Option<Axis> {
        ALL_AXES.get(i).copied()
    }

    /// The axis of a letter (either case).
    pub fn from_letter(c: char) -> Option<Axis> {
        ALL_AXES
            .into_iter()
            .find(|a| a.letter() == c.to_ascii_uppercase())
    }

    /// Its letter.
    pub const fn letter(self) -> char {
        b"XYZABCUVW"[self as usize] as char
    }

    /// Its letter as a string ("X").
    pub const fn name(self) -> &'static str {
        match self {
            Axis::X => "X",
            Axis::Y => "Y",
            Axis::Z => "Z",
            Axis::A => "A",
            Axis::B => "B",
            Axis::C => "C",
            Axis::U => "U",
            Axis::V => "V",
            Axis::W => "W",
        }
    }

    /// The name of the axis at index `i` ("?" beyond the nine).
    pub fn name_of(i: usize) -> &'static str {
        Axis::from_index(i).map_or("?", Axis::name)
    }

    /// The axes the stack carries: the first [`MAX_AXES`].
    pub fn carried() -> impl Iterator<Item = Axis> + Clone {
        ALL_AXES.into_iter().take(MAX_AXES)
    }
}

/// One `T` per axis the stack carries, indexed by [`Axis`] or by index; reads as
/// the array it wraps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(transparent)]
#[repr(transparent)]
pub struct Axes<T>(pub [T; MAX_AXES]);

impl<T> Axes<T> {
    /// Each axis's value from `f`.
    pub fn from_fn(mut f: impl FnMut(Axis) -> T) -> Self {
        Axes(std::array::from_fn(|i| f(ALL_AXES[i])))
    }

    /// Each value through `f`.
    pub fn map<U>(self, f: impl FnMut(T) -> U) -> Axes<U> {
        Axes(self.0.map(f))
    }

    /// (axis, value) pairs.
    pub fn iter_axes(&self) -> impl Iterator<Item = (Axis, &T)> {
        Axis::carried().zip(self.0.iter())
    }

    /// The array.
    pub fn into_array(self) -> [T; MAX_AXES] {
        self.0
    }
}

impl<T: Copy> Axes<T> {
    /// The same value on every axis.
    pub const fn splat(v: T) -> Self {
        Axes([v; MAX_AXES])
    }

    /// A point of the path (X, Y, Z) on the axes; any further axis at `rest`.
    pub fn from_xyz(xyz: [T; 3], rest: T) -> Self {
        Axes(std::array::from_fn(|i| if i < 3 { xyz[i] } else { rest }))
    }

    /// X, Y and Z: the Cartesian part the path geometry ([`crate::Vec3`]) is about.
    pub fn xyz(&self) -> [T; 3] {
        [self.0[0], self.0[1], self.0[2]]
    }
}

const _: () = assert!(MAX_AXES >= 3, "the path geometry needs X, Y and Z");

impl<T: Default + Copy> Default for Axes<T> {
    fn default() -> Self {
        Axes([T::default(); MAX_AXES])
    }
}

impl<T> From<[T; MAX_AXES]> for Axes<T> {
    fn from(a: [T; MAX_AXES]) -> Self {
        Axes(a)
    }
}

impl<T> From<Axes<T>> for [T; MAX_AXES] {
    fn from(a: Axes<T>) -> Self {
        a.0
    }
}

impl<T> Deref for Axes<T> {
    type Target = [T; MAX_AXES];
    fn deref(&self) -> &[T; MAX_AXES] {
        &self.0
    }
}

impl<T> DerefMut for Axes<T> {
    fn deref_mut(&mut self) -> &mut [T; MAX_AXES] {
        &mut self.0
    }
}

impl<T> Index<Axis> for Axes<T> {
    type Output = T;
    fn index(&self, a: Axis) -> &T {
        &self.0[a.index()]
    }
}

impl<T> IndexMut<Axis> for Axes<T> {
    fn index_mut(&mut self, a: Axis) -> &mut T {
        &mut self.0[a.index()]
    }
}

impl<T> Index<usize> for Axes<T> {
    type Output = T;
    fn index(&self, i: usize) -> &T {
        &self.0[i]
    }
}

impl<T> IndexMut<usize> for Axes<T> {
    fn index_mut(&mut self, i: usize) -> &mut T {
        &mut self.0[i]
    }
}

impl<'a, T> IntoIterator for &'a Axes<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl<'a, T> IntoIterator for &'a mut Axes<T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter_mut()
    }
}

impl<T> IntoIterator for Axes<T> {
    type Item = T;
    type IntoIter = std::array::IntoIter<T, MAX_AXES>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letters_and_indices_round_trip_for_the_nine() {
        for (i, a) in ALL_AXES.into_iter().enumerate() {
            assert_eq!(a.index(), i);
            assert_eq!(Axis::from_index(i), Some(a));
            assert_eq!(Axis::from_letter(a.letter()), Some(a));
            assert_eq!(Axis::from_letter(a.letter().to_ascii_lowercase()), Some(a));
            assert_eq!(a.name().chars().next(), Some(a.letter()));
        }
        assert_eq!(Axis::from_index(9), None);
        assert_eq!(Axis::from_letter('Q'), None);
        assert_eq!(Axis::name_of(9), "?");
    }

    #[test]
    fn axes_index_by_axis_and_by_number_alike() {
        let mut v = Axes::from_fn(|a| a.index() as f64 * 10.0);
        v[Axis::Y] += 1.0;
        assert_eq!(v[1], 11.0);
        assert_eq!(v.map(|x| x * 2.0)[Axis::X], 0.0);
        assert_eq!(Axis::carried().count(), MAX_AXES);
        assert_eq!(
            v.iter_axes().last().map(|(a, _)| a.index()),
            Some(MAX_AXES - 1)
        );
        let arr: [f64; MAX_AXES] = v.into();
        assert_eq!(Axes::from(arr), v);
        assert_eq!(Axes::splat(1u8).iter().sum::<u8>() as usize, MAX_AXES);
        // RON: as the plain list
        let ron = ron::to_string(&Axes::splat(2.5)).unwrap();
        assert_eq!(ron::from_str::<Axes<f64>>(&ron).unwrap(), Axes::splat(2.5));
    }
}
