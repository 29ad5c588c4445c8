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

/// Two-operand lane operations, each one AVX intrinsic on the two
/// registers.
#[cfg(target_arch = "x86_64")]
macro_rules! binary_ops {
    ($($(#[$doc:meta])* $name:ident => $intrinsic:expr;)*) => {
        $(
            $(#[$doc])*
            ///
            /// # Safety
            ///
            /// Outside AVX code, call only where [`available`] is true.
            #[inline]
            #[target_feature(enable = "avx")]
            pub fn $name(self, o: Self) -> Self {
                Self($intrinsic(self.0, o.0))
            }
        )*
    };
}

/// Eight `f32` lanes in a `__m256`. Only constructible inside AVX code.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct F32x8(__m256);

#[cfg(target_arch = "x86_64")]
impl F32x8 {
    binary_ops! {
        /// IEEE product per lane.
        mul => _mm256_mul_ps;
        /// `if self > o { self } else { o }` per lane (`maxps`), as
        /// [`super::f32x8::max`].
        max => _mm256_max_ps;
        /// `if self < o { self } else { o }` per lane (`minps`), as
        /// [`super::f32x8::min`].
        min => _mm256_min_ps;
        /// IEEE difference per lane.
        sub => _mm256_sub_ps;
        /// Mask of `self ≥ o` (false on NaN), as the facade's `cmp_ge`.
        cmp_ge => _mm256_cmp_ps::<_CMP_GE_OQ>;
        /// Mask of `self < o` (false on NaN), as the facade's `cmp_lt`.
        cmp_lt => _mm256_cmp_ps::<_CMP_LT_OQ>;
        /// Mask of `self > o` (false on NaN), as the facade's `cmp_gt`.
        cmp_gt => _mm256_cmp_ps::<_CMP_GT_OQ>;
        /// Bitwise and (the facade's `&`, by its method name).
        bitand => _mm256_and_ps;
        /// Bitwise or (the facade's `|`, by its method name).
        bitor => _mm256_or_ps;
        /// IEEE sum per lane.
        add => _mm256_add_ps;
        /// IEEE quotient per lane.
        div => _mm256_div_ps;
        /// Mask of `self ≠ o` (true on NaN), as the facade's `cmp_ne`.
        cmp_ne => _mm256_cmp_ps::<_CMP_NEQ_UQ>;
    }

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

    /// The lanes `a`, in order.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn new(a: [f32; 8]) -> Self {
        Self::load(&a)
    }

    /// `|self|` per lane (the sign bit cleared), as the facade's `abs`.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn abs(self) -> Self {
        F32x8(_mm256_and_ps(
            self.0,
            _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)),
        ))
    }

    /// Bit `k` set where lane `k`'s sign bit is (a mask's lanes), as the
    /// facade's `move_mask`.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn move_mask(self) -> u32 {
        _mm256_movemask_ps(self.0) as u32
    }

    /// Whether any lane's sign bit is set, as the facade's `any`.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn any(self) -> bool {
        self.move_mask() != 0
    }

    /// Each lane truncated toward zero to `i32` (`vcvttps2dq`: NaN and
    /// out-of-range lanes give `i32::MIN`), as an array: for lanes in
    /// `i32`'s range (not NaN) the same as the facade's
    /// `trunc_int_array` (which saturates the others).
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn trunc_int_array(self) -> [i32; 8] {
        let mut out = [0i32; 8];
        // SAFETY: `out` is eight `i32` (32 bytes), exactly what an
        // unaligned 256-bit store writes.
        unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), _mm256_cvttps_epi32(self.0)) };
        out
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

    /// Lanes `a`, in order (an unaligned 256-bit load).
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn load(a: &[f32; 8]) -> Self {
        // SAFETY: `a` is eight `f32` (32 bytes), exactly what an unaligned
        // 256-bit load reads.
        F32x8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
    }

    /// `t` where the mask `self` (lanes all ones or all zeros) is set, `f`
    /// elsewhere, as [`super::f32x8::blend`].
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn blend(self, t: Self, f: Self) -> Self {
        F32x8(_mm256_blendv_ps(f.0, t.0, self.0))
    }

    /// Lanes 0–3 and 4–7 converted to `f64` (exactly), as
    /// [`super::f32x8::widen`].
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn widen(self) -> [F64x4; 2] {
        [
            F64x4(_mm256_cvtps_pd(_mm256_castps256_ps128(self.0))),
            F64x4(_mm256_cvtps_pd(_mm256_extractf128_ps::<1>(self.0))),
        ]
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

/// Eight `i32` lanes in a `__m256i`, with AVX2's integer arithmetic.
/// Only constructible inside AVX2 code.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct I32x8(__m256i);

#[cfg(target_arch = "x86_64")]
impl I32x8 {
    /// Every lane `v`.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn splat(v: i32) -> Self {
        I32x8(_mm256_set1_epi32(v))
    }

    /// Lanes `a`, in order (an unaligned 256-bit load).
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn load(a: &[i32; 8]) -> Self {
        // SAFETY: `a` is eight `i32` (32 bytes), exactly what an unaligned
        // 256-bit load reads.
        I32x8(unsafe { _mm256_loadu_si256(a.as_ptr().cast()) })
    }

    /// Writes the lanes to `a`, in order (an unaligned 256-bit store).
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn store(self, a: &mut [i32; 8]) {
        // SAFETY: `a` is eight `i32` (32 bytes), exactly what an unaligned
        // 256-bit store writes.
        unsafe { _mm256_storeu_si256(a.as_mut_ptr().cast(), self.0) }
    }

    /// Wrapping sum per lane, as the facade's `i32x8` `+`.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn add(self, o: Self) -> Self {
        I32x8(_mm256_add_epi32(self.0, o.0))
    }

    /// Mask of `self > o` per lane (all ones or all zeros), as the
    /// facade's `i32x8::cmp_gt`.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn cmp_gt(self, o: Self) -> Self {
        I32x8(_mm256_cmpgt_epi32(self.0, o.0))
    }

    /// The larger lane of `self` and `o`, per lane.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn max(self, o: Self) -> Self {
        I32x8(_mm256_max_epi32(self.0, o.0))
    }

    /// Bitwise and.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn bitand(self, o: Self) -> Self {
        I32x8(_mm256_and_si256(self.0, o.0))
    }

    /// Bit `k` set where lane `k`'s sign bit is (a mask's lanes), as the
    /// facade's `move_mask`.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn move_mask(self) -> u32 {
        _mm256_movemask_ps(_mm256_castsi256_ps(self.0)) as u32
    }

    /// The lanes where the mask `m` (lanes all ones or all zeros) is set,
    /// 0 elsewhere: the facade's `m.cast_i32() & self`.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn masked(self, m: F32x8) -> Self {
        I32x8(_mm256_and_si256(_mm256_castps_si256(m.0), self.0))
    }

    /// The lanes as an array.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn to_array(self) -> [i32; 8] {
        let mut out = [0; 8];
        self.store(&mut out);
        out
    }
}

/// Four `f64` lanes in a `__m256d`. Only constructible inside AVX code.
/// Compares return masks of the same type (lanes all ones or all zeros).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct F64x4(__m256d);

#[cfg(target_arch = "x86_64")]
impl F64x4 {
    binary_ops! {
        /// IEEE sum per lane.
        add => _mm256_add_pd;
        /// IEEE difference per lane.
        sub => _mm256_sub_pd;
        /// IEEE product per lane.
        mul => _mm256_mul_pd;
        /// IEEE quotient per lane.
        div => _mm256_div_pd;
        /// Mask of `self < o` (false on NaN), as the facade's `cmp_lt`.
        cmp_lt => _mm256_cmp_pd::<_CMP_LT_OQ>;
        /// Mask of `self > o` (false on NaN), as the facade's `cmp_gt`.
        cmp_gt => _mm256_cmp_pd::<_CMP_GT_OQ>;
        /// Mask of `self ≤ o` (false on NaN), as the facade's `cmp_le`.
        cmp_le => _mm256_cmp_pd::<_CMP_LE_OQ>;
        /// Mask of `self ≥ o` (false on NaN), as the facade's `cmp_ge`.
        cmp_ge => _mm256_cmp_pd::<_CMP_GE_OQ>;
        /// Bitwise and (the facade's `&`, by its method name).
        bitand => _mm256_and_pd;
        /// Bitwise or (the facade's `|`, by its method name).
        bitor => _mm256_or_pd;
        /// `if self > o { self } else { o }` per lane (`vmaxpd`: a NaN in
        /// either lane, or two equal lanes, give `o`), as the facade's `max`.
        max => _mm256_max_pd;
        /// `if self < o { self } else { o }` per lane (`vminpd`), as the
        /// facade's `min`.
        min => _mm256_min_pd;
    }

    /// The lanes `a`, in order.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn new(a: [f64; 4]) -> Self {
        F64x4(_mm256_setr_pd(a[0], a[1], a[2], a[3]))
    }

    /// Bitwise not, the facade's operator name.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn not(self) -> Self {
        F64x4(_mm256_xor_pd(
            self.0,
            _mm256_castsi256_pd(_mm256_set1_epi64x(-1)),
        ))
    }

    /// Every lane `v`.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn splat(v: f64) -> Self {
        F64x4(_mm256_set1_pd(v))
    }

    /// Lanes `a`, in order (an unaligned 256-bit load).
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn load(a: &[f64; 4]) -> Self {
        // SAFETY: `a` is four `f64` (32 bytes), exactly what an unaligned
        // 256-bit load reads.
        F64x4(unsafe { _mm256_loadu_pd(a.as_ptr()) })
    }

    /// The lanes as an array.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn to_array(self) -> [f64; 4] {
        let mut out = [0.0f64; 4];
        // SAFETY: `out` is four `f64` (32 bytes), exactly what an
        // unaligned 256-bit store writes.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) };
        out
    }

    /// `self & !o`, bitwise.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn and_not(self, o: Self) -> Self {
        F64x4(_mm256_andnot_pd(o.0, self.0))
    }

    /// `t` where the mask `self` is set, `f` elsewhere, as the facade's
    /// `blend`.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn blend(self, t: Self, f: Self) -> Self {
        F64x4(_mm256_blendv_pd(f.0, t.0, self.0))
    }

    /// Bit `k` set where lane `k`'s top bit is, as the facade's
    /// `move_mask`.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn move_mask(self) -> u32 {
        _mm256_movemask_pd(self.0) as u32
    }
}

impl F64x4 {
    /// Each lane rounded to `f32` (`vcvtpd2ps`: round to nearest even, as
    /// `as f32`), in order.
    ///
    /// # Safety
    ///
    /// Outside AVX code, call only where [`available`] is true.
    #[inline]
    #[target_feature(enable = "avx")]
    pub fn to_f32_array(self) -> [f32; 4] {
        let mut out = [0.0f32; 4];
        // SAFETY: `out` is four `f32` (16 bytes), exactly what an
        // unaligned 128-bit store writes.
        unsafe { _mm_storeu_ps(out.as_mut_ptr(), _mm256_cvtpd_ps(self.0)) };
        out
    }
}

/// Four `u64` lanes in a `__m256i`, with wrapping integer arithmetic (as
/// `u64::wrapping_*`): what hashing several keys at once needs. Its
/// operations need AVX2. Only constructible inside AVX2 code.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub struct U64x4(__m256i);

#[cfg(target_arch = "x86_64")]
impl U64x4 {
    /// The lanes `a`, in order.
    ///
    /// # Safety
    ///
    /// Outside AVX2 code, call only where the CPU has AVX2
    /// ([`super::level::runs_v3`]).
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn new(a: [u64; 4]) -> Self {
        U64x4(_mm256_setr_epi64x(
            a[0] as i64,
            a[1] as i64,
            a[2] as i64,
            a[3] as i64,
        ))
    }

    /// Every lane `v`.
    ///
    /// # Safety
    ///
    /// As [`U64x4::new`].
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn splat(v: u64) -> Self {
        U64x4(_mm256_set1_epi64x(v as i64))
    }

    /// `self + o` per lane, wrapping.
    ///
    /// # Safety
    ///
    /// As [`U64x4::new`].
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn wrapping_add(self, o: Self) -> Self {
        U64x4(_mm256_add_epi64(self.0, o.0))
    }

    /// `self ^ o` per lane.
    ///
    /// # Safety
    ///
    /// As [`U64x4::new`].
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn xor(self, o: Self) -> Self {
        U64x4(_mm256_xor_si256(self.0, o.0))
    }

    /// `self >> N` per lane (logical).
    ///
    /// # Safety
    ///
    /// As [`U64x4::new`].
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn shr<const N: i32>(self) -> Self {
        U64x4(_mm256_srli_epi64::<N>(self.0))
    }

    /// `self · c` per lane, wrapping (mod 2⁶⁴): AVX2 multiplies only
    /// 32-bit halves, so the low halves' full product plus the cross
    /// products shifted up (the high halves' product falls off the top).
    ///
    /// # Safety
    ///
    /// As [`U64x4::new`].
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn wrapping_mul(self, c: u64) -> Self {
        let (c_lo, c_hi) = (
            _mm256_set1_epi64x((c & 0xffff_ffff) as i64),
            _mm256_set1_epi64x((c >> 32) as i64),
        );
        let low = _mm256_mul_epu32(self.0, c_lo);
        let cross = _mm256_add_epi64(
            _mm256_mul_epu32(_mm256_srli_epi64::<32>(self.0), c_lo),
            _mm256_mul_epu32(self.0, c_hi),
        );
        U64x4(_mm256_add_epi64(low, _mm256_slli_epi64::<32>(cross)))
    }

    /// Each lane's high 32 bits as an `f64`, exactly (`(v >> 32) as
    /// f64`): below 2³², so OR-ing them into the mantissa of 2⁵² and
    /// subtracting 2⁵² is exact.
    ///
    /// # Safety
    ///
    /// As [`U64x4::new`].
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn high_half_to_f64(self) -> F64x4 {
        let biased = _mm256_or_si256(
            _mm256_srli_epi64::<32>(self.0),
            _mm256_set1_epi64x(0x4330_0000_0000_0000),
        );
        F64x4(_mm256_sub_pd(
            _mm256_castsi256_pd(biased),
            _mm256_set1_pd(4_503_599_627_370_496.0),
        ))
    }

    /// The lanes as an array.
    ///
    /// # Safety
    ///
    /// As [`U64x4::new`].
    #[inline]
    #[target_feature(enable = "avx,avx2")]
    pub fn to_array(self) -> [u64; 4] {
        let mut out = [0u64; 4];
        // SAFETY: `out` is four `u64` (32 bytes), exactly what an
        // unaligned 256-bit store writes.
        unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), self.0) };
        out
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::super::scalar;
    use super::*;

    /// The tests' random source: a 64-bit LCG from `seed`.
    fn lcg(seed: u64) -> impl FnMut() -> u64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state
        }
    }

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
        let mut lcg = lcg(0x3c6e_f372_fe94_f82b);
        let mut next = || (lcg() >> 32) as u32;
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

    #[target_feature(enable = "avx")]
    #[allow(clippy::type_complexity)]
    fn run_f32_more(a: [f32; 8], b: [f32; 8]) -> ([f32; 8], [f32; 8], [[f64; 4]; 2]) {
        let (x, y) = (F32x8::load(&a), F32x8::load(&b));
        let mask =
            F32x8::from_lanes(super::super::f32x8::new(b).cmp_lt(super::super::f32x8::new(a)));
        let w = x.widen();
        (
            x.sub(y).to_array(),
            mask.blend(x, y).to_array(),
            [w[0].to_array(), w[1].to_array()],
        )
    }

    #[target_feature(enable = "avx")]
    #[allow(clippy::type_complexity)]
    fn run_f64(a: [f64; 4], b: [f64; 4]) -> ([[f64; 4]; 3], [u32; 2], [[f64; 4]; 4], u32) {
        let (x, y) = (F64x4::load(&a), F64x4::load(&b));
        let (lt, gt) = (x.cmp_lt(y), x.cmp_gt(y));
        (
            [
                x.add(y).to_array(),
                x.sub(y).to_array(),
                x.mul(y).to_array(),
            ],
            [lt.move_mask(), gt.move_mask()],
            [
                lt.bitand(gt.bitor(lt)).to_array(),
                lt.bitor(gt).to_array(),
                lt.and_not(gt).to_array(),
                lt.blend(x, y).to_array(),
            ],
            x.move_mask(),
        )
    }

    /// The lane operations added for the triangle test, against the scalar
    /// twin: `f32` difference, blend and widening; `f64` sum, difference,
    /// product (NaN results as NaN: their payload is not fixed), compares,
    /// mask logic, blend and sign mask, bit for bit.
    #[test]
    fn avx_triangle_lanes_match_the_scalar_twin() {
        use super::super::scalar::{f32x8 as S32, f64x4 as S64};
        if !available() {
            eprintln!("no AVX on this CPU: nothing to check");
            return;
        }
        let mut next = lcg(0x510e_527f_ade6_82d1);
        let specials = [
            0.0f64,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
            5e-324,
            1.0,
            -2.5,
        ];
        let same32 = |x: f32, y: f32| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan());
        let same64 = |x: f64, y: f64| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan());
        for _ in 0..50_000 {
            let mut lane32 = || {
                let r = next();
                if r.is_multiple_of(5) {
                    specials[(r >> 8) as usize % specials.len()] as f32
                } else {
                    f32::from_bits((r >> 32) as u32)
                }
            };
            let a: [f32; 8] = std::array::from_fn(|_| lane32());
            let b: [f32; 8] = std::array::from_fn(|_| lane32());
            // SAFETY: AVX is available (checked above).
            let (sub, blend, wide) = unsafe { run_f32_more(a, b) };
            let (sa, sb) = (S32::new(a), S32::new(b));
            let twin = (sa - sb).to_array();
            assert!((0..8).all(|k| same32(sub[k], twin[k])), "{a:?} {b:?}");
            let pick = sb.cmp_lt(sa).blend(sa, sb).to_array();
            assert_eq!(
                blend.map(f32::to_bits),
                pick.map(f32::to_bits),
                "{a:?} {b:?}"
            );
            let w = sa.widen();
            for h in 0..2 {
                assert_eq!(wide[h].map(f64::to_bits), w[h].to_array().map(f64::to_bits));
            }
            let mut lane64 = || {
                let r = next();
                if r.is_multiple_of(5) {
                    specials[(r >> 8) as usize % specials.len()]
                } else if r % 5 == 1 {
                    (r >> 11) as f64 * 1e-3 - 4e12
                } else {
                    f64::from_bits(next())
                }
            };
            let x: [f64; 4] = std::array::from_fn(|_| lane64());
            let mut y: [f64; 4] = std::array::from_fn(|_| lane64());
            y[3] = x[3];
            // SAFETY: AVX is available (checked above).
            let (arith, masks, logic, sign) = unsafe { run_f64(x, y) };
            let (sx, sy) = (S64::new(x), S64::new(y));
            for (got, want) in arith.iter().zip([sx + sy, sx - sy, sx * sy]) {
                let want = want.to_array();
                assert!((0..4).all(|k| same64(got[k], want[k])), "{x:?} {y:?}");
            }
            let (lt, gt) = (sx.cmp_lt(sy), sx.cmp_gt(sy));
            assert_eq!(masks, [lt.move_mask(), gt.move_mask()], "{x:?} {y:?}");
            let bits = |v: S64| v.to_array().map(f64::to_bits);
            let want = [lt & (gt | lt), lt | gt, lt & !gt, lt.blend(sx, sy)].map(bits);
            assert_eq!(logic.map(|v| v.map(f64::to_bits)), want, "{x:?} {y:?}");
            assert_eq!(sign, sx.move_mask(), "{x:?}");
        }
    }

    #[target_feature(enable = "avx,avx2")]
    fn run_counts(a: [f32; 8], b: [f32; 8], c: [i32; 8], d: i32) -> (u32, u32, [i32; 8]) {
        let (x, y) = (F32x8::load(&a), F32x8::load(&b));
        let (ge, lt, gt) = (x.cmp_ge(y), x.cmp_lt(y), x.cmp_gt(y));
        let both = ge.bitand(lt.blend(ge, lt));
        let sum = I32x8::load(&c).add(I32x8::splat(d).masked(ge));
        (
            _mm256_movemask_ps(ge.0) as u32
                | (_mm256_movemask_ps(lt.0) as u32) << 8
                | (_mm256_movemask_ps(gt.0) as u32) << 16,
            _mm256_movemask_ps(both.0) as u32,
            sum.to_array(),
        )
    }

    /// The counting kernel's operations against the scalar twin: `≥`, `<`
    /// and `>` masks (false on NaN), mask `and`, and the masked wrapping
    /// integer sum.
    #[test]
    fn avx2_count_lanes_match_the_scalar_twin() {
        use super::super::scalar::{f32x8 as S32, i32x8 as I32};
        if !crate::simd::level::Level::V3.supported() {
            eprintln!("no AVX2 on this CPU: nothing to check");
            return;
        }
        let mut next = lcg(0x9b05_688c_2b3e_6c1f);
        let specials = [0.0f32, -0.0, f32::NAN, f32::INFINITY, 1.0, -1.0];
        for _ in 0..50_000 {
            let mut lane = || {
                let r = next();
                if r.is_multiple_of(3) {
                    specials[(r >> 8) as usize % specials.len()]
                } else {
                    f32::from_bits((r >> 32) as u32)
                }
            };
            let a: [f32; 8] = std::array::from_fn(|_| lane());
            let mut b: [f32; 8] = std::array::from_fn(|_| lane());
            b[7] = a[7];
            let c: [i32; 8] = std::array::from_fn(|_| next() as i32);
            let d = next() as i32;
            // SAFETY: AVX2 is available (checked above).
            let (masks, both, sum) = unsafe { run_counts(a, b, c, d) };
            let (sa, sb) = (S32::new(a), S32::new(b));
            let (ge, lt, gt) = (sa.cmp_ge(sb), sa.cmp_lt(sb), sa.cmp_gt(sb));
            let want = ge.move_mask() | lt.move_mask() << 8 | gt.move_mask() << 16;
            assert_eq!(masks, want, "{a:?} {b:?}");
            assert_eq!(both, (ge & lt.blend(ge, lt)).move_mask(), "{a:?} {b:?}");
            let want = I32::new(c) + (ge.cast_i32() & I32::splat(d));
            assert_eq!(sum, want.to_array(), "{a:?} {b:?}");
        }
    }

    #[target_feature(enable = "avx,avx2")]
    fn run_u64(a: [u64; 4], b: [u64; 4], c: u64) -> [[u64; 4]; 5] {
        let (x, y) = (U64x4::new(a), U64x4::new(b));
        let f = x.high_half_to_f64().to_array().map(f64::to_bits);
        let g = F64x4::new(a.map(|v| (v >> 7) as f64)).to_f32_array();
        [
            x.wrapping_add(y).to_array(),
            x.xor(U64x4::splat(c)).shr::<29>().to_array(),
            x.wrapping_mul(c).to_array(),
            f,
            [0, 1, 2, 3].map(|k| u64::from(g[k].to_bits())),
        ]
    }

    /// Every `U64x4` operation (and `F64x4::to_f32_array`) against `u64`
    /// and `as` arithmetic, bit for bit.
    #[test]
    fn u64_lanes_match_scalar_arithmetic() {
        if !crate::simd::level::runs_v3() {
            eprintln!("no AVX2 on this CPU: nothing to check");
            return;
        }
        let mut lcg = lcg(0x9e37_79b9_7f4a_7c15);
        for _ in 0..100_000 {
            let a: [u64; 4] = std::array::from_fn(|_| lcg());
            let b: [u64; 4] = std::array::from_fn(|_| lcg());
            let c = lcg();
            // SAFETY: the CPU has AVX2 (checked above).
            let [add, shifted, mul, high, narrowed] = unsafe { run_u64(a, b, c) };
            for k in 0..4 {
                assert_eq!(add[k], a[k].wrapping_add(b[k]));
                assert_eq!(shifted[k], (a[k] ^ c) >> 29);
                assert_eq!(mul[k], a[k].wrapping_mul(c));
                assert_eq!(high[k], ((a[k] >> 32) as f64).to_bits());
                assert_eq!(
                    narrowed[k],
                    u64::from((((a[k] >> 7) as f64) as f32).to_bits())
                );
            }
        }
    }
}
