//! The scalar twin of the facade: the same types and operations on plain
//! arrays, one lane at a time in ordinary Rust. This is the reference
//! semantics; the tests hold every SIMD operation to it bit for bit.

use std::ops::{
    Add, AddAssign, BitAnd, BitAndAssign, BitOr, BitOrAssign, BitXor, Div, Mul, Not, Sub, SubAssign,
};

/// Operations shared by the float and the integer lane types.
macro_rules! lanes_common {
    ($name:ident, $t:ty, $bits:ty, $n:literal) => {
        #[doc = concat!(stringify!($n), " lanes of `", stringify!($t), "`, one at a time.")]
        #[derive(Debug, Clone, Copy, Default)]
        pub struct $name(pub [$t; $n]);

        impl $name {
            /// All lanes zero.
            pub const ZERO: Self = Self([0 as $t; $n]);

            /// The lanes `a`.
            pub const fn new(a: [$t; $n]) -> Self {
                Self(a)
            }

            /// Every lane `v`.
            pub fn splat(v: $t) -> Self {
                Self([v; $n])
            }

            /// The lanes as an array.
            pub fn to_array(self) -> [$t; $n] {
                self.0
            }

            /// Lanes `s[..N]` (panics when `s` is shorter).
            pub fn load(s: &[$t]) -> Self {
                let mut a = [0 as $t; $n];
                a.copy_from_slice(&s[..$n]);
                Self(a)
            }

            /// Each lane's bits.
            fn bits(self) -> [$bits; $n] {
                self.0.map(|v| v.to_bits())
            }

            /// Lanes from bits.
            fn from_bits(b: [$bits; $n]) -> Self {
                Self(b.map(<$t>::from_bits))
            }

            /// Lanewise `f(a, b)` on the bits.
            fn zip_bits(self, o: Self, f: impl Fn($bits, $bits) -> $bits) -> Self {
                let (a, b) = (self.bits(), o.bits());
                Self::from_bits(std::array::from_fn(|k| f(a[k], b[k])))
            }

            /// Lanewise `f(a, b)`.
            fn zip(self, o: Self, f: impl Fn($t, $t) -> $t) -> Self {
                Self(std::array::from_fn(|k| f(self.0[k], o.0[k])))
            }

            /// All ones where `f(a, b)`, zeros elsewhere.
            #[allow(dead_code)] // u32x4 has no compares
            fn mask(self, o: Self, f: impl Fn($t, $t) -> bool) -> Self {
                Self::from_bits(std::array::from_fn(|k| {
                    if f(self.0[k], o.0[k]) {
                        !0
                    } else {
                        0
                    }
                }))
            }

            /// `t` where the mask `self` is set, `f` elsewhere: a lane of
            /// the mask is all ones or all zeros.
            pub fn blend(self, t: Self, f: Self) -> Self {
                let (m, t, f) = (self.bits(), t.0, f.0);
                Self(std::array::from_fn(|k| if m[k] == 0 { f[k] } else { t[k] }))
            }

            /// The top bit of each lane (bit k = lane k).
            pub fn move_mask(self) -> u32 {
                let top = <$bits>::BITS - 1;
                let b = self.bits();
                (0..$n).fold(0, |m, k| m | (((b[k] >> top) & 1) as u32) << k)
            }

            /// Whether any lane's top bit is set.
            pub fn any(self) -> bool {
                self.move_mask() != 0
            }
        }

        impl From<[$t; $n]> for $name {
            fn from(a: [$t; $n]) -> Self {
                Self(a)
            }
        }

        impl AddAssign for $name {
            fn add_assign(&mut self, o: Self) {
                *self = *self + o;
            }
        }

        impl SubAssign for $name {
            fn sub_assign(&mut self, o: Self) {
                *self = *self - o;
            }
        }

        impl BitAnd for $name {
            type Output = Self;
            fn bitand(self, o: Self) -> Self {
                self.zip_bits(o, |a, b| a & b)
            }
        }

        impl BitOr for $name {
            type Output = Self;
            fn bitor(self, o: Self) -> Self {
                self.zip_bits(o, |a, b| a | b)
            }
        }

        impl BitXor for $name {
            type Output = Self;
            fn bitxor(self, o: Self) -> Self {
                self.zip_bits(o, |a, b| a ^ b)
            }
        }

        impl BitAndAssign for $name {
            fn bitand_assign(&mut self, o: Self) {
                *self = *self & o;
            }
        }

        impl BitOrAssign for $name {
            fn bitor_assign(&mut self, o: Self) {
                *self = *self | o;
            }
        }

        impl Not for $name {
            type Output = Self;
            fn not(self) -> Self {
                Self::from_bits(self.bits().map(|b| !b))
            }
        }
    };
}

/// Float lanes: IEEE arithmetic, compares, min / max, sqrt, abs.
macro_rules! float_lanes {
    ($name:ident, $t:ty, $bits:ty, $n:literal) => {
        lanes_common!($name, $t, $bits, $n);

        impl $name {
            /// All lanes one.
            pub const ONE: Self = Self([1.0; $n]);

            /// Mask of `self == o`.
            pub fn cmp_eq(self, o: Self) -> Self {
                self.mask(o, |a, b| a == b)
            }

            /// Mask of `self != o`.
            pub fn cmp_ne(self, o: Self) -> Self {
                self.mask(o, |a, b| a != b)
            }

            /// Mask of `self < o`.
            pub fn cmp_lt(self, o: Self) -> Self {
                self.mask(o, |a, b| a < b)
            }

            /// Mask of `self <= o`.
            pub fn cmp_le(self, o: Self) -> Self {
                self.mask(o, |a, b| a <= b)
            }

            /// Mask of `self > o`.
            pub fn cmp_gt(self, o: Self) -> Self {
                self.mask(o, |a, b| a > b)
            }

            /// Mask of `self >= o`.
            pub fn cmp_ge(self, o: Self) -> Self {
                self.mask(o, |a, b| a >= b)
            }

            /// `if self > o { self } else { o }` per lane.
            pub fn max(self, o: Self) -> Self {
                self.zip(o, |a, b| if a > b { a } else { b })
            }

            /// `if self < o { self } else { o }` per lane.
            pub fn min(self, o: Self) -> Self {
                self.zip(o, |a, b| if a < b { a } else { b })
            }

            /// Correctly rounded square root.
            pub fn sqrt(self) -> Self {
                Self(self.0.map(<$t>::sqrt))
            }

            /// The sign bits cleared.
            pub fn abs(self) -> Self {
                Self(self.0.map(<$t>::abs))
            }
        }

        impl Add for $name {
            type Output = Self;
            fn add(self, o: Self) -> Self {
                self.zip(o, |a, b| a + b)
            }
        }

        impl Sub for $name {
            type Output = Self;
            fn sub(self, o: Self) -> Self {
                self.zip(o, |a, b| a - b)
            }
        }

        impl Mul for $name {
            type Output = Self;
            fn mul(self, o: Self) -> Self {
                self.zip(o, |a, b| a * b)
            }
        }

        impl Div for $name {
            type Output = Self;
            fn div(self, o: Self) -> Self {
                self.zip(o, |a, b| a / b)
            }
        }
    };
}

/// Integer lanes: wrapping arithmetic, compares.
macro_rules! int_lanes {
    ($name:ident, $t:ty, $n:literal) => {
        lanes_common!($name, $t, $t, $n);

        impl Add for $name {
            type Output = Self;
            fn add(self, o: Self) -> Self {
                self.zip(o, <$t>::wrapping_add)
            }
        }

        impl Sub for $name {
            type Output = Self;
            fn sub(self, o: Self) -> Self {
                self.zip(o, <$t>::wrapping_sub)
            }
        }

        impl Mul for $name {
            type Output = Self;
            fn mul(self, o: Self) -> Self {
                self.zip(o, <$t>::wrapping_mul)
            }
        }
    };
}

/// Integers are their own bits.
trait Bits: Sized {
    fn to_bits(self) -> Self;
    fn from_bits(b: Self) -> Self;
}

impl Bits for i32 {
    fn to_bits(self) -> Self {
        self
    }
    fn from_bits(b: Self) -> Self {
        b
    }
}

impl Bits for u32 {
    fn to_bits(self) -> Self {
        self
    }
    fn from_bits(b: Self) -> Self {
        b
    }
}

float_lanes!(f32x8, f32, u32, 8);
float_lanes!(f64x4, f64, u64, 4);
float_lanes!(f32x4, f32, u32, 4);
int_lanes!(i32x8, i32, 8);
int_lanes!(i32x4, i32, 4);
int_lanes!(u32x4, u32, 4);

/// Signed compares and min / max of `i32` lanes.
macro_rules! signed {
    ($name:ident) => {
        impl $name {
            /// Mask of `self == o`.
            pub fn cmp_eq(self, o: Self) -> Self {
                self.mask(o, |a, b| a == b)
            }

            /// Mask of `self > o`.
            pub fn cmp_gt(self, o: Self) -> Self {
                self.mask(o, |a, b| a > b)
            }

            /// Mask of `self < o`.
            pub fn cmp_lt(self, o: Self) -> Self {
                self.mask(o, |a, b| a < b)
            }
        }
    };
}

signed!(i32x8);
signed!(i32x4);

impl i32x4 {
    /// Lanewise maximum.
    pub fn max(self, o: Self) -> Self {
        self.zip(o, i32::max)
    }

    /// Lanewise minimum.
    pub fn min(self, o: Self) -> Self {
        self.zip(o, i32::min)
    }
}

/// Bit casts between float and integer lanes of one width.
macro_rules! bit_casts {
    ($float:ident, $to_int:ident, $int:ident, $it:ty, $to_float:ident, $ft:ty) => {
        impl $float {
            #[doc = concat!("The lanes' bits as `", stringify!($int), "`.")]
            pub fn $to_int(self) -> $int {
                $int(self.0.map(|v| v.to_bits() as $it))
            }
        }

        impl $int {
            #[doc = concat!("The lanes' bits as `", stringify!($float), "`.")]
            pub fn $to_float(self) -> $float {
                $float(self.0.map(|v| <$ft>::from_bits(v as u32)))
            }
        }
    };
}

bit_casts!(f32x8, cast_i32, i32x8, i32, cast_f32, f32);
bit_casts!(f32x4, cast_u32, u32x4, u32, cast_f32, f32);
bit_casts!(f32x4, cast_i32, i32x4, i32, cast_f32, f32);

impl f32x8 {
    /// Truncation toward zero as `as i32`: saturating, NaN to 0.
    pub fn trunc_int(self) -> i32x8 {
        i32x8(self.0.map(|v| v as i32))
    }

    /// The eight lanes widened to `f64` (exact): lanes 0–3 and 4–7.
    pub fn widen(self) -> [f64x4; 2] {
        [0, 4].map(|k| f64x4(std::array::from_fn(|i| f64::from(self.0[k + i]))))
    }
}

impl f32x4 {
    /// Truncation toward zero as `as i32`: saturating, NaN to 0.
    pub fn trunc_int(self) -> i32x4 {
        i32x4(self.0.map(|v| v as i32))
    }

    /// The 4×4 transpose: lane `j` of row `i` becomes lane `i` of row `j`.
    pub fn transpose(rows: [f32x4; 4]) -> [f32x4; 4] {
        std::array::from_fn(|j| f32x4(std::array::from_fn(|i| rows[i].0[j])))
    }
}
