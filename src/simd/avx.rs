//! Eight `f32` lanes in one AVX register, for kernels chosen at run time.
//!
//! The crate's lane types follow the SIMD level the build targets (what
//! `wide` compiles for), so a baseline x86-64 build runs `f32x8` as two
//! SSE halves even on a CPU with AVX. A hot kernel can instead be written
//! twice, once on [`super::f32x8`] and once on [`F32x8`] inside a
//! `#[target_feature(enable = "avx")]` function, and pick one per call by
//! [`available`]. Every operation here is the same IEEE operation as the
//! facade's of the same name (correctly rounded `mul`; `max` / `min` by
//! the `maxps` / `minps` rule, NaN and equal lanes giving the right
//! operand; `le` an ordered compare, false on NaN), so both copies give
//! the same bits; `tests` holds each against the scalar twin.

#[cfg(target_arch = "x86_64")]
use core::arch::x86_64::*;

/// Whether the CPU running this has AVX and `PENUMBRA_SIMD` does not
/// force the baseline (`super::level`; checked once).
#[inline]
pub fn available() -> bool {
    static AVX: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX.get_or_init(|| {
        let forced = matches!(
            super::level::from_env(),
            Ok(Some(super::level::Level::Baseline))
        );
        #[cfg(target_arch = "x86_64")]
        {
            !forced && std::is_x86_feature_detected!("avx")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = forced;
            false
        }
    })
}

/// Eight `f32` lanes in a `__m256`. Only constructible inside AVX code.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct F32x8(__m256);

#[cfg(target_arch = "x86_64")]
impl F32x8 {
    /// Every lane `v`.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn splat(v: f32) -> Self {
        F32x8(_mm256_set1_ps(v))
    }

    /// The lanes of a facade `f32x8`, in order.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn from_lanes(v: super::f32x8) -> Self {
        let a = v.to_array();
        F32x8(_mm256_setr_ps(
            a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7],
        ))
    }

    /// The lanes as an array.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn to_array(self) -> [f32; 8] {
        let mut out = [0.0f32; 8];
        // SAFETY: `out` is eight `f32` (32 bytes), exactly what an
        // unaligned 256-bit store writes.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) };
        out
    }

    /// IEEE product per lane.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn mul(self, o: Self) -> Self {
        F32x8(_mm256_mul_ps(self.0, o.0))
    }

    /// `if self > o { self } else { o }` per lane (`maxps`), as
    /// [`super::f32x8::max`].
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn max(self, o: Self) -> Self {
        F32x8(_mm256_max_ps(self.0, o.0))
    }

    /// `if self < o { self } else { o }` per lane (`minps`), as
    /// [`super::f32x8::min`].
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn min(self, o: Self) -> Self {
        F32x8(_mm256_min_ps(self.0, o.0))
    }

    /// Bit `k` set where lane `k` has `self ≤ o` (false on NaN), as
    /// `cmp_le(..).move_mask()` of the facade.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn le_mask(self, o: Self) -> u32 {
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0)) as u32
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::super::scalar;
    use super::*;

    #[target_feature(enable = "avx")]
    fn run(a: [f32; 8], b: [f32; 8]) -> ([f32; 8], [f32; 8], [f32; 8], u32, [f32; 8]) {
        let (x, y) = (
            F32x8::from_lanes(super::super::f32x8::new(a)),
            F32x8::from_lanes(super::super::f32x8::new(b)),
        );
        (
            x.mul(y).to_array(),
            x.max(y).to_array(),
            x.min(y).to_array(),
            x.le_mask(y),
            F32x8::splat(a[3]).to_array(),
        )
    }

    /// Every operation against the scalar twin, bit for bit, on random
    /// and special values (zeros of both signs, NaN, infinities,
    /// subnormals, equal lanes).
    #[test]
    fn avx_lanes_match_the_scalar_twin() {
        if !available() {
            eprintln!("no AVX on this CPU: nothing to check");
            return;
        }
        let specials = [
            0.0f32,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e-45,
            -3e-39,
            1.0,
            -1.0,
            f32::MAX,
        ];
        let mut state = 0x3c6e_f372_fe94_f82bu64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 32) as u32
        };
        for _ in 0..100_000 {
            let mut lane = || {
                let r = next();
                if r % 4 == 0 {
                    specials[(r / 4) as usize % specials.len()]
                } else {
                    f32::from_bits(next())
                }
            };
            let a: [f32; 8] = std::array::from_fn(|_| lane());
            let mut b: [f32; 8] = std::array::from_fn(|_| lane());
            b[7] = a[7];
            // SAFETY: AVX is available (checked above).
            let (mul, max, min, le, splat) = unsafe { run(a, b) };
            let (sa, sb) = (scalar::f32x8::new(a), scalar::f32x8::new(b));
            let bits = |v: [f32; 8]| v.map(f32::to_bits);
            // A product's NaN payload is not fixed (which operand's NaN
            // survives depends on the operand order the compiler picks for
            // a commutative multiply), so NaN products compare as NaN, as
            // in the facade's own tests; every other product bit for bit.
            let same = |x: f32, y: f32| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan());
            let twin = (sa * sb).to_array();
            assert!(
                (0..8).all(|k| same(mul[k], twin[k])),
                "{a:?} {b:?}: {mul:?} vs {twin:?}"
            );
            assert_eq!(bits(max), bits(sa.max(sb).to_array()), "{a:?} {b:?}");
            assert_eq!(bits(min), bits(sa.min(sb).to_array()), "{a:?} {b:?}");
            assert_eq!(le, sa.cmp_le(sb).move_mask(), "{a:?} {b:?}");
            assert_eq!(bits(splat), [a[3].to_bits(); 8]);
        }
    }
}
