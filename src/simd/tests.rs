//! Every facade operation against its scalar twin, lane by lane and bit
//! for bit, on random inputs mixed with the special values (±0, ±∞, NaNs,
//! subnormals, the extremes, equal lanes).
//!
//! Arithmetic that yields NaN is compared by class only (the payload of a
//! NaN produced by arithmetic is not fixed by IEEE or by Rust); every other
//! result, NaNs passed through included, is compared bit for bit.

use super::scalar;
use crate::sampling::SplitMix64;

const ROUNDS: usize = 20_000;

/// The test inputs' generator: SplitMix64 and a draw below a bound.
struct Rng(SplitMix64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next_u64()
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

/// A lane value: special values a third of the time, small integers and
/// short decimals (which make equal and tied lanes likely) or raw bits
/// otherwise.
trait Lane: Copy + std::fmt::Debug {
    fn random(rng: &mut Rng) -> Self;
    /// Bits for comparison, and whether the value is a NaN.
    fn key(self) -> (u64, bool);
}

macro_rules! float_lane {
    ($t:ty, $bits:ty) => {
        impl Lane for $t {
            fn random(rng: &mut Rng) -> Self {
                const SPECIAL: [$t; 16] = [
                    0.0,
                    -0.0,
                    1.0,
                    -1.0,
                    0.5,
                    <$t>::INFINITY,
                    <$t>::NEG_INFINITY,
                    <$t>::NAN,
                    -<$t>::NAN,
                    <$t>::MIN_POSITIVE,
                    -<$t>::MIN_POSITIVE,
                    <$t>::MAX,
                    <$t>::MIN,
                    <$t>::EPSILON,
                    2147483648.0,
                    -2147483904.0,
                ];
                match rng.below(6) {
                    0 | 1 => SPECIAL[rng.below(SPECIAL.len() as u64) as usize],
                    // Subnormals, and NaNs with payloads.
                    2 => {
                        let b = rng.next() as $bits;
                        if rng.below(2) == 0 {
                            <$t>::from_bits(b >> 12)
                        } else {
                            <$t>::from_bits(b | <$t>::NAN.to_bits())
                        }
                    }
                    3 => (rng.below(17) as i64 - 8) as $t,
                    4 => (rng.below(4001) as i64 - 2000) as $t * 1e-3,
                    _ => <$t>::from_bits(rng.next() as $bits),
                }
            }

            fn key(self) -> (u64, bool) {
                (self.to_bits() as u64, self.is_nan())
            }
        }
    };
}

float_lane!(f32, u32);
float_lane!(f64, u64);

macro_rules! int_lane {
    ($t:ty) => {
        impl Lane for $t {
            fn random(rng: &mut Rng) -> Self {
                const SPECIAL: [$t; 6] = [0, 1, 2, <$t>::MAX, <$t>::MIN, <$t>::MAX - 1];
                match rng.below(4) {
                    0 => SPECIAL[rng.below(SPECIAL.len() as u64) as usize],
                    1 => (rng.below(17) as i64 - 8) as $t,
                    _ => rng.next() as $t,
                }
            }

            fn key(self) -> (u64, bool) {
                (self as u64, false)
            }
        }
    };
}

int_lane!(i32);
int_lane!(u32);

/// Random lanes, some copied from `other` (equal lanes) or its negation.
fn lanes<T: Lane, const N: usize>(rng: &mut Rng, other: &[T; N]) -> [T; N] {
    std::array::from_fn(|k| {
        if rng.below(4) == 0 {
            other[k]
        } else {
            T::random(rng)
        }
    })
}

/// Whether the facade's lanes are the twin's: bit for bit, or both NaN
/// when `nan_class`.
#[track_caller]
fn same<T: Lane, const N: usize>(
    op: &str,
    inputs: &str,
    simd: [T; N],
    twin: [T; N],
    nan_class: bool,
) {
    for k in 0..N {
        let ((a, a_nan), (b, b_nan)) = (simd[k].key(), twin[k].key());
        let ok = a == b || (nan_class && a_nan && b_nan);
        assert!(
            ok,
            "{op} lane {k}: facade {:?} twin {:?} on {inputs}",
            simd[k], twin[k]
        );
    }
}

/// Random masks: each lane all ones or all zeros.
fn mask_bits<const N: usize>(rng: &mut Rng) -> [bool; N] {
    std::array::from_fn(|_| rng.below(2) == 0)
}

macro_rules! float_tests {
    ($name:ident, $ty:ident, $t:ty, $bits:ty, $n:literal) => {
        #[test]
        fn $name() {
            use super::$ty as V;
            use scalar::$ty as S;
            let mut rng = Rng(SplitMix64::new(stringify!($ty).len() as u64 * 7919 + $n));
            let ones = <$t>::from_bits(!0);
            for _ in 0..ROUNDS {
                let a: [$t; $n] = lanes(&mut rng, &[0.0; $n]);
                let b: [$t; $n] = lanes(&mut rng, &a);
                let b = if rng.below(8) == 0 { a.map(|v| -v) } else { b };
                let (va, vb, sa, sb) = (V::new(a), V::new(b), S::new(a), S::new(b));
                let inputs = format!("{a:?} {b:?}");
                let i = &inputs;
                same("add", i, (va + vb).to_array(), (sa + sb).to_array(), true);
                same("sub", i, (va - vb).to_array(), (sa - sb).to_array(), true);
                same("mul", i, (va * vb).to_array(), (sa * sb).to_array(), true);
                same("div", i, (va / vb).to_array(), (sa / sb).to_array(), true);
                same("sqrt", i, va.sqrt().to_array(), sa.sqrt().to_array(), true);
                let (mut x, mut y) = (va, sa);
                x += vb;
                y += sb;
                same("add_assign", i, x.to_array(), y.to_array(), true);
                x -= va;
                y -= sa;
                same("sub_assign", i, x.to_array(), y.to_array(), true);
                same("abs", i, va.abs().to_array(), sa.abs().to_array(), false);
                same(
                    "max",
                    i,
                    va.max(vb).to_array(),
                    sa.max(sb).to_array(),
                    false,
                );
                same(
                    "min",
                    i,
                    va.min(vb).to_array(),
                    sa.min(sb).to_array(),
                    false,
                );
                same("and", i, (va & vb).to_array(), (sa & sb).to_array(), false);
                same("or", i, (va | vb).to_array(), (sa | sb).to_array(), false);
                same("xor", i, (va ^ vb).to_array(), (sa ^ sb).to_array(), false);
                same("not", i, (!va).to_array(), (!sa).to_array(), false);
                let (mut x, mut y) = (va, sa);
                x &= vb;
                y &= sb;
                x |= va;
                y |= sa;
                same("and/or_assign", i, x.to_array(), y.to_array(), false);
                let compares: [(&str, V, S); 6] = [
                    ("cmp_eq", va.cmp_eq(vb), sa.cmp_eq(sb)),
                    ("cmp_ne", va.cmp_ne(vb), sa.cmp_ne(sb)),
                    ("cmp_lt", va.cmp_lt(vb), sa.cmp_lt(sb)),
                    ("cmp_le", va.cmp_le(vb), sa.cmp_le(sb)),
                    ("cmp_gt", va.cmp_gt(vb), sa.cmp_gt(sb)),
                    ("cmp_ge", va.cmp_ge(vb), sa.cmp_ge(sb)),
                ];
                for (op, m, sm) in compares {
                    same(op, i, m.to_array(), sm.to_array(), false);
                    assert_eq!(m.move_mask(), sm.move_mask(), "{op} move_mask on {i}");
                    assert_eq!(m.any(), sm.any(), "{op} any on {i}");
                    same(
                        op,
                        i,
                        m.blend(va, vb).to_array(),
                        sm.blend(sa, sb).to_array(),
                        false,
                    );
                }
                // Random bits: move_mask reads the sign bits.
                assert_eq!(va.move_mask(), sa.move_mask(), "move_mask on {i}");
                let m = mask_bits::<$n>(&mut rng).map(|on| if on { ones } else { 0.0 });
                let (vm, sm) = (V::new(m), S::new(m));
                same(
                    "blend",
                    i,
                    vm.blend(va, vb).to_array(),
                    sm.blend(sa, sb).to_array(),
                    false,
                );
                same(
                    "splat",
                    i,
                    V::splat(a[0]).to_array(),
                    S::splat(a[0]).to_array(),
                    false,
                );
                same(
                    "load",
                    i,
                    V::load(&b).to_array(),
                    S::load(&b).to_array(),
                    false,
                );
                same("from", i, V::from(a).to_array(), a, false);
            }
            same("ZERO", "", V::ZERO.to_array(), S::ZERO.to_array(), false);
            same("ONE", "", V::ONE.to_array(), S::ONE.to_array(), false);
            same("default", "", V::default().to_array(), [0.0; $n], false);
        }
    };
}

float_tests!(f32x8_agrees_with_its_twin, f32x8, f32, u32, 8);
float_tests!(f64x4_agrees_with_its_twin, f64x4, f64, u64, 4);
float_tests!(f32x4_agrees_with_its_twin, f32x4, f32, u32, 4);

macro_rules! int_tests {
    ($name:ident, $ty:ident, $t:ty, $n:literal) => {
        #[test]
        fn $name() {
            use super::$ty as V;
            use scalar::$ty as S;
            let mut rng = Rng(SplitMix64::new(stringify!($ty).len() as u64 * 104729 + $n));
            for _ in 0..ROUNDS {
                let a: [$t; $n] = lanes(&mut rng, &[0; $n]);
                let b: [$t; $n] = lanes(&mut rng, &a);
                let (va, vb, sa, sb) = (V::new(a), V::new(b), S::new(a), S::new(b));
                let inputs = format!("{a:?} {b:?}");
                let i = &inputs;
                // Wrapping: overflow lanes included.
                same("add", i, (va + vb).to_array(), (sa + sb).to_array(), false);
                same("sub", i, (va - vb).to_array(), (sa - sb).to_array(), false);
                same("mul", i, (va * vb).to_array(), (sa * sb).to_array(), false);
                let (mut x, mut y) = (va, sa);
                x += vb;
                y += sb;
                x -= va;
                y -= sa;
                same("add/sub_assign", i, x.to_array(), y.to_array(), false);
                same("and", i, (va & vb).to_array(), (sa & sb).to_array(), false);
                same("or", i, (va | vb).to_array(), (sa | sb).to_array(), false);
                same("xor", i, (va ^ vb).to_array(), (sa ^ sb).to_array(), false);
                same("not", i, (!va).to_array(), (!sa).to_array(), false);
                let (mut x, mut y) = (va, sa);
                x &= vb;
                y &= sb;
                x |= va;
                y |= sa;
                same("and/or_assign", i, x.to_array(), y.to_array(), false);
                let ones = !0;
                let m = mask_bits::<$n>(&mut rng).map(|on| if on { ones } else { 0 });
                let (vm, sm) = (V::new(m), S::new(m));
                same(
                    "blend",
                    i,
                    vm.blend(va, vb).to_array(),
                    sm.blend(sa, sb).to_array(),
                    false,
                );
                same(
                    "splat",
                    i,
                    V::splat(a[0]).to_array(),
                    S::splat(a[0]).to_array(),
                    false,
                );
                same(
                    "load",
                    i,
                    V::load(&b).to_array(),
                    S::load(&b).to_array(),
                    false,
                );
                same("from", i, V::from(a).to_array(), a, false);
            }
            same("ZERO", "", V::ZERO.to_array(), S::ZERO.to_array(), false);
            same("default", "", V::default().to_array(), [0; $n], false);
        }
    };
}

int_tests!(i32x8_agrees_with_its_twin, i32x8, i32, 8);
int_tests!(i32x4_agrees_with_its_twin, i32x4, i32, 4);
int_tests!(u32x4_agrees_with_its_twin, u32x4, u32, 4);

macro_rules! signed_tests {
    ($name:ident, $ty:ident, $n:literal) => {
        #[test]
        fn $name() {
            use super::$ty as V;
            use scalar::$ty as S;
            let mut rng = Rng(SplitMix64::new(31 * $n));
            for _ in 0..ROUNDS {
                let a: [i32; $n] = lanes(&mut rng, &[0; $n]);
                let b: [i32; $n] = lanes(&mut rng, &a);
                let (va, vb, sa, sb) = (V::new(a), V::new(b), S::new(a), S::new(b));
                let i = &format!("{a:?} {b:?}");
                for (op, m, sm) in [
                    ("cmp_eq", va.cmp_eq(vb), sa.cmp_eq(sb)),
                    ("cmp_gt", va.cmp_gt(vb), sa.cmp_gt(sb)),
                    ("cmp_lt", va.cmp_lt(vb), sa.cmp_lt(sb)),
                ] {
                    same(op, i, m.to_array(), sm.to_array(), false);
                    assert_eq!(m.move_mask(), sm.move_mask(), "{op} move_mask on {i}");
                    assert_eq!(m.any(), sm.any(), "{op} any on {i}");
                    same(
                        op,
                        i,
                        m.blend(va, vb).to_array(),
                        sm.blend(sa, sb).to_array(),
                        false,
                    );
                }
                assert_eq!(va.move_mask(), sa.move_mask(), "move_mask on {i}");
            }
        }
    };
}

signed_tests!(i32x8_compares_agree, i32x8, 8);
signed_tests!(i32x4_compares_agree, i32x4, 4);

#[test]
fn i32x4_min_max_agree() {
    let mut rng = Rng(SplitMix64::new(77));
    for _ in 0..ROUNDS {
        let a: [i32; 4] = lanes(&mut rng, &[0; 4]);
        let b: [i32; 4] = lanes(&mut rng, &a);
        let (va, vb) = (super::i32x4::new(a), super::i32x4::new(b));
        let (sa, sb) = (scalar::i32x4::new(a), scalar::i32x4::new(b));
        let i = &format!("{a:?} {b:?}");
        same(
            "max",
            i,
            va.max(vb).to_array(),
            sa.max(sb).to_array(),
            false,
        );
        same(
            "min",
            i,
            va.min(vb).to_array(),
            sa.min(sb).to_array(),
            false,
        );
    }
}

/// Bit casts, truncation and the transpose.
#[test]
fn conversions_agree() {
    let mut rng = Rng(SplitMix64::new(5));
    for _ in 0..ROUNDS {
        let a: [f32; 8] = lanes(&mut rng, &[0.0; 8]);
        let i = &format!("{a:?}");
        let (v, s) = (super::f32x8::new(a), scalar::f32x8::new(a));
        same(
            "f32x8 cast_i32",
            i,
            v.cast_i32().to_array(),
            s.cast_i32().to_array(),
            false,
        );
        let (wv, ws) = (v.widen(), s.widen());
        for h in 0..2 {
            same("f32x8 widen", i, wv[h].to_array(), ws[h].to_array(), false);
        }
        // Saturating, NaN to 0: `as i32`.
        same(
            "f32x8 trunc_int",
            i,
            v.trunc_int().to_array(),
            s.trunc_int().to_array(),
            false,
        );
        same(
            "f32x8 trunc_int is as",
            i,
            s.trunc_int().to_array(),
            a.map(|x| x as i32),
            false,
        );
        let back = v.cast_i32().cast_f32().to_array();
        same("f32x8 cast round trip", i, back, a, false);
        let bits = s.cast_i32().to_array();
        let (vi, si) = (super::i32x8::new(bits), scalar::i32x8::new(bits));
        same(
            "i32x8 cast_f32",
            i,
            vi.cast_f32().to_array(),
            si.cast_f32().to_array(),
            false,
        );

        let q = [a[0], a[1], a[2], a[3]];
        let (v, s) = (super::f32x4::new(q), scalar::f32x4::new(q));
        same(
            "f32x4 cast_u32",
            i,
            v.cast_u32().to_array(),
            s.cast_u32().to_array(),
            false,
        );
        same(
            "f32x4 cast_i32",
            i,
            v.cast_i32().to_array(),
            s.cast_i32().to_array(),
            false,
        );
        let u = s.cast_u32().to_array();
        let (vu, su) = (super::u32x4::new(u), scalar::u32x4::new(u));
        same(
            "u32x4 cast_f32",
            i,
            vu.cast_f32().to_array(),
            su.cast_f32().to_array(),
            false,
        );
        let n = s.cast_i32().to_array();
        let (vn, sn) = (super::i32x4::new(n), scalar::i32x4::new(n));
        same(
            "i32x4 cast_f32",
            i,
            vn.cast_f32().to_array(),
            sn.cast_f32().to_array(),
            false,
        );
        // Saturating, NaN to 0: `as i32`.
        same(
            "trunc_int",
            i,
            v.trunc_int().to_array(),
            s.trunc_int().to_array(),
            false,
        );
        same(
            "trunc_int is as",
            i,
            s.trunc_int().to_array(),
            q.map(|x| x as i32),
            false,
        );

        let rows: [[f32; 4]; 4] = std::array::from_fn(|_| lanes(&mut rng, &[0.0; 4]));
        let t = super::f32x4::transpose(rows.map(super::f32x4::new)).map(|r| r.to_array());
        let st = scalar::f32x4::transpose(rows.map(scalar::f32x4::new)).map(|r| r.to_array());
        for (r, (a, b)) in t.iter().zip(&st).enumerate() {
            same("transpose", &format!("{rows:?} row {r}"), *a, *b, false);
        }
    }
}

/// The twin is the semantics the docs state: spot checks where a SIMD
/// level could plausibly differ.
#[test]
fn twin_semantics_at_the_edges() {
    use scalar::{f32x4, f32x8, i32x8};
    let nan = f32::NAN;
    // max / min: NaN or equal lanes give the right operand.
    let a = f32x4::new([nan, 1.0, 0.0, -0.0]);
    let b = f32x4::new([2.0, nan, -0.0, 0.0]);
    let max = a.max(b).to_array();
    assert_eq!(max[0], 2.0);
    assert!(max[1].is_nan());
    assert_eq!(max.map(f32::to_bits)[2..], [(-0.0f32).to_bits(), 0]);
    let min = a.min(b).to_array();
    assert_eq!(min[0], 2.0);
    assert!(min[1].is_nan());
    // cmp_ne is true on NaN, the others false.
    let n = f32x8::splat(nan);
    assert_eq!(n.cmp_ne(n).move_mask(), 0xff);
    assert_eq!(
        super::f32x8::splat(nan)
            .cmp_ne(super::f32x8::splat(nan))
            .move_mask(),
        0xff
    );
    assert_eq!(n.cmp_eq(n).move_mask() | n.cmp_le(n).move_mask(), 0);
    // Wrapping integer arithmetic.
    let m = i32x8::splat(i32::MAX) + i32x8::splat(1);
    assert_eq!(m.to_array(), [i32::MIN; 8]);
    // Saturating truncation.
    let t = f32x4::new([nan, 3e9, -3e9, -1.9]).trunc_int().to_array();
    assert_eq!(t, [0, i32::MAX, i32::MIN, -1]);
    let t = f32x8::new([nan, 3e9, -3e9, -1.9, 2.5, -0.0, 1e-30, -nan]).trunc_int();
    assert_eq!(t.to_array(), [0, i32::MAX, i32::MIN, -1, 2, 0, 0, 0]);
    let v = super::f32x8::new([nan, 3e9, -3e9, -1.9, 2.5, -0.0, 1e-30, -nan]).trunc_int();
    assert_eq!(v.to_array(), t.to_array());
}
