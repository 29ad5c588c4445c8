//! The SIMD facade: the crate's own lane types, and the only module that
//! imports `wide`.
//!
//! Each type is a newtype over the `wide` vector of the same shape and
//! exposes only operations whose result is fixed bit for bit by their
//! definition, whatever SIMD level `wide` compiles for (design rule 1):
//! IEEE add, sub, mul, div and sqrt (correctly rounded), compares,
//! selects, bit operations and bit casts, wrapping integer arithmetic,
//! saturating truncation, and `min` / `max` defined as one compare and a
//! pick (NaN and equal lanes give the right operand). There is no fused
//! multiply-add and no approximate reciprocal to call: code written on
//! these types cannot depend on the SIMD level.
//!
//! Where `wide` itself differs between levels, the facade picks one
//! meaning: `cmp_ne` is IEEE `!=` (true on NaN; `wide`'s AVX f32x8 and
//! f64x4 `cmp_ne` are false there, its SSE ones true), and `min` / `max`
//! are the x86 `minps` / `maxps` rule, which other targets get by compare
//! and blend.
//!
//! Masks are vectors of the same type whose lanes are all ones or all
//! zeros, as the compares return them; `blend` and `move_mask` take such
//! masks (`blend` picks whole lanes by them).
//!
//! [`scalar`] is the twin of every type and operation on plain arrays,
//! the reference semantics: the tests hold each operation against it lane
//! by lane, bit for bit, on random and special inputs.

#![allow(non_camel_case_types)]

pub mod avx;
#[forbid(unsafe_code)]
pub mod level;
#[forbid(unsafe_code)]
pub mod scalar;
#[cfg(test)]
#[forbid(unsafe_code)]
mod tests;

use std::ops::{
    Add, AddAssign, BitAnd, BitAndAssign, BitOr, BitOrAssign, BitXor, Div, Mul, Not, Sub, SubAssign,
};

/// Operations shared by the float and the integer lane types.
macro_rules! lanes_common {
    ($name:ident, $wide:ident, $t:ty, $n:literal) => {
        #[doc = concat!(stringify!($n), " lanes of `", stringify!($t), "`.")]
        #[derive(Debug, Clone, Copy, Default)]
        #[repr(transparent)]
        pub struct $name(wide::$wide);

        impl $name {
            /// All lanes zero.
            pub const ZERO: Self = Self::new([0 as $t; $n]);

            /// The lanes `a`.
            #[inline(always)]
            pub const fn new(a: [$t; $n]) -> Self {
                Self(wide::$wide::new(a))
            }

            /// Every lane `v`.
            #[inline(always)]
            pub fn splat(v: $t) -> Self {
                Self(wide::$wide::splat(v))
            }

            /// The lanes as an array.
            #[inline(always)]
            pub fn to_array(self) -> [$t; $n] {
                self.0.to_array()
            }

            /// Lanes `s[..N]` (panics when `s` is shorter).
            #[inline(always)]
            pub fn load(s: &[$t]) -> Self {
                let mut a = [0 as $t; $n];
                a.copy_from_slice(&s[..$n]);
                Self::new(a)
            }

            /// `t` where the mask `self` is set, `f` elsewhere.
            #[inline(always)]
            pub fn blend(self, t: Self, f: Self) -> Self {
                Self(self.0.blend(t.0, f.0))
            }
        }

        impl From<[$t; $n]> for $name {
            #[inline(always)]
            fn from(a: [$t; $n]) -> Self {
                Self::new(a)
            }
        }

        impl Add for $name {
            type Output = Self;
            #[inline(always)]
            fn add(self, o: Self) -> Self {
                Self(self.0 + o.0)
            }
        }

        impl Sub for $name {
            type Output = Self;
            #[inline(always)]
            fn sub(self, o: Self) -> Self {
                Self(self.0 - o.0)
            }
        }

        impl Mul for $name {
            type Output = Self;
            #[inline(always)]
            fn mul(self, o: Self) -> Self {
                Self(self.0 * o.0)
            }
        }

        impl AddAssign for $name {
            #[inline(always)]
            fn add_assign(&mut self, o: Self) {
                *self = *self + o;
            }
        }

        impl SubAssign for $name {
            #[inline(always)]
            fn sub_assign(&mut self, o: Self) {
                *self = *self - o;
            }
        }

        impl BitAnd for $name {
            type Output = Self;
            #[inline(always)]
            fn bitand(self, o: Self) -> Self {
                Self(self.0 & o.0)
            }
        }

        impl BitOr for $name {
            type Output = Self;
            #[inline(always)]
            fn bitor(self, o: Self) -> Self {
                Self(self.0 | o.0)
            }
        }

        impl BitXor for $name {
            type Output = Self;
            #[inline(always)]
            fn bitxor(self, o: Self) -> Self {
                Self(self.0 ^ o.0)
            }
        }

        impl BitAndAssign for $name {
            #[inline(always)]
            fn bitand_assign(&mut self, o: Self) {
                *self = *self & o;
            }
        }

        impl BitOrAssign for $name {
            #[inline(always)]
            fn bitor_assign(&mut self, o: Self) {
                *self = *self | o;
            }
        }

        impl Not for $name {
            type Output = Self;
            #[inline(always)]
            fn not(self) -> Self {
                Self(!self.0)
            }
        }
    };
}

/// Sign-bit masks of the lane types that have them.
macro_rules! move_mask {
    ($name:ident) => {
        impl $name {
            /// The top bit of each lane (bit k = lane k).
            #[inline(always)]
            pub fn move_mask(self) -> u32 {
                self.0.move_mask() as u32
            }

            /// Whether any lane's top bit is set.
            #[inline(always)]
            pub fn any(self) -> bool {
                self.move_mask() != 0
            }
        }
    };
}

/// Float lanes: IEEE arithmetic, compares, min / max, sqrt, abs.
macro_rules! float_lanes {
    ($name:ident, $wide:ident, $t:ty, $n:literal) => {
        lanes_common!($name, $wide, $t, $n);
        move_mask!($name);

        impl $name {
            /// All lanes one.
            pub const ONE: Self = Self::new([1.0; $n]);

            /// Mask of `self == o` (false on NaN).
            #[inline(always)]
            pub fn cmp_eq(self, o: Self) -> Self {
                use wide::CmpEq;
                Self(self.0.cmp_eq(o.0))
            }

            /// Mask of `self != o` (true on NaN).
            #[inline(always)]
            pub fn cmp_ne(self, o: Self) -> Self {
                !self.cmp_eq(o)
            }

            /// Mask of `self < o` (false on NaN).
            #[inline(always)]
            pub fn cmp_lt(self, o: Self) -> Self {
                use wide::CmpLt;
                Self(self.0.cmp_lt(o.0))
            }

            /// Mask of `self <= o` (false on NaN).
            #[inline(always)]
            pub fn cmp_le(self, o: Self) -> Self {
                use wide::CmpLe;
                Self(self.0.cmp_le(o.0))
            }

            /// Mask of `self > o` (false on NaN).
            #[inline(always)]
            pub fn cmp_gt(self, o: Self) -> Self {
                use wide::CmpGt;
                Self(self.0.cmp_gt(o.0))
            }

            /// Mask of `self >= o` (false on NaN).
            #[inline(always)]
            pub fn cmp_ge(self, o: Self) -> Self {
                use wide::CmpGe;
                Self(self.0.cmp_ge(o.0))
            }

            /// `if self > o { self } else { o }` per lane: a NaN in either
            /// lane, or two equal lanes (±0), give `o`.
            #[inline(always)]
            pub fn max(self, o: Self) -> Self {
                #[cfg(all(
                    any(target_arch = "x86", target_arch = "x86_64"),
                    target_feature = "sse2"
                ))]
                {
                    // `maxps` / `maxpd`: exactly this rule.
                    Self(self.0.fast_max(o.0))
                }
                #[cfg(not(all(
                    any(target_arch = "x86", target_arch = "x86_64"),
                    target_feature = "sse2"
                )))]
                {
                    self.cmp_gt(o).blend(self, o)
                }
            }

            /// `if self < o { self } else { o }` per lane: a NaN in either
            /// lane, or two equal lanes (±0), give `o`.
            #[inline(always)]
            pub fn min(self, o: Self) -> Self {
                #[cfg(all(
                    any(target_arch = "x86", target_arch = "x86_64"),
                    target_feature = "sse2"
                ))]
                {
                    // `minps` / `minpd`: exactly this rule.
                    Self(self.0.fast_min(o.0))
                }
                #[cfg(not(all(
                    any(target_arch = "x86", target_arch = "x86_64"),
                    target_feature = "sse2"
                )))]
                {
                    self.cmp_lt(o).blend(self, o)
                }
            }

            /// Correctly rounded square root.
            #[inline(always)]
            pub fn sqrt(self) -> Self {
                Self(self.0.sqrt())
            }

            /// The sign bits cleared.
            #[inline(always)]
            pub fn abs(self) -> Self {
                self & Self::splat(<$t>::from_bits(!0 >> 1))
            }
        }

        impl Div for $name {
            type Output = Self;
            #[inline(always)]
            fn div(self, o: Self) -> Self {
                Self(self.0 / o.0)
            }
        }
    };
}

float_lanes!(f32x8, f32x8, f32, 8);
float_lanes!(f64x4, f64x4, f64, 4);
float_lanes!(f32x4, f32x4, f32, 4);
// Integer lanes: wrapping arithmetic; `i32` ones also compare.
lanes_common!(i32x8, i32x8, i32, 8);
lanes_common!(i32x4, i32x4, i32, 4);
lanes_common!(u32x4, u32x4, u32, 4);
move_mask!(i32x8);
move_mask!(i32x4);

/// Signed compares of `i32` lanes.
macro_rules! signed_compares {
    ($name:ident) => {
        impl $name {
            /// Mask of `self == o`.
            #[inline(always)]
            pub fn cmp_eq(self, o: Self) -> Self {
                use wide::CmpEq;
                Self(self.0.cmp_eq(o.0))
            }

            /// Mask of `self > o`.
            #[inline(always)]
            pub fn cmp_gt(self, o: Self) -> Self {
                use wide::CmpGt;
                Self(self.0.cmp_gt(o.0))
            }

            /// Mask of `self < o`.
            #[inline(always)]
            pub fn cmp_lt(self, o: Self) -> Self {
                use wide::CmpLt;
                Self(self.0.cmp_lt(o.0))
            }
        }
    };
}

signed_compares!(i32x8);
signed_compares!(i32x4);

impl i32x4 {
    /// Lanewise maximum.
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        Self(self.0.max(o.0))
    }

    /// Lanewise minimum.
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        Self(self.0.min(o.0))
    }
}

/// Bit casts between float and integer lanes of one width.
macro_rules! bit_casts {
    ($float:ident, $to_int:ident, $int:ident, $to_float:ident) => {
        impl $float {
            #[doc = concat!("The lanes' bits as `", stringify!($int), "`.")]
            #[inline(always)]
            pub fn $to_int(self) -> $int {
                $int(bytemuck::cast(self.0))
            }
        }

        impl $int {
            #[doc = concat!("The lanes' bits as `", stringify!($float), "`.")]
            #[inline(always)]
            pub fn $to_float(self) -> $float {
                $float(bytemuck::cast(self.0))
            }
        }
    };
}

bit_casts!(f32x8, cast_i32, i32x8, cast_f32);
bit_casts!(f32x4, cast_u32, u32x4, cast_f32);
bit_casts!(f32x4, cast_i32, i32x4, cast_f32);

impl f32x8 {
    /// Truncation toward zero as `as i32`: saturating, NaN to 0.
    #[inline(always)]
    pub fn trunc_int(self) -> i32x8 {
        i32x8(self.0.trunc_int())
    }

    /// [`f32x8::trunc_int`]'s lanes as an array: for lanes in `i32`'s
    /// range (not NaN) the same as `simd::avx::F32x8::trunc_int_array`.
    #[inline(always)]
    pub fn trunc_int_array(self) -> [i32; 8] {
        self.trunc_int().to_array()
    }

    /// The eight lanes widened to `f64` (exact): lanes 0–3 and 4–7.
    #[inline(always)]
    pub fn widen(self) -> [f64x4; 2] {
        let a = self.to_array();
        [
            f64x4::new([a[0] as f64, a[1] as f64, a[2] as f64, a[3] as f64]),
            f64x4::new([a[4] as f64, a[5] as f64, a[6] as f64, a[7] as f64]),
        ]
    }
}

impl f32x4 {
    /// Truncation toward zero as `as i32`: saturating, NaN to 0.
    #[inline(always)]
    pub fn trunc_int(self) -> i32x4 {
        i32x4(self.0.trunc_int())
    }

    /// The 4×4 transpose: lane `j` of row `i` becomes lane `i` of row `j`.
    #[inline(always)]
    pub fn transpose(rows: [f32x4; 4]) -> [f32x4; 4] {
        // Destructured rather than `map`ped: no array copies to optimise away.
        let [a, b, c, d] = rows;
        let [a, b, c, d] = wide::f32x4::transpose([a.0, b.0, c.0, d.0]);
        [f32x4(a), f32x4(b), f32x4(c), f32x4(d)]
    }
}
