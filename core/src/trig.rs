//! Sine and cosine of the sensor head's face angles on the chip, in integer arithmetic.
//!
//! The sensor board takes the sine and cosine of two angles only, the face angles of the
//! near-field calibration (validated to 5-85 deg), once per configuration. libm's `sinf`
//! and `cosf` (what `f32::sin`/`cos` are without `std`) work in double precision and carry a
//! general argument reduction for arguments up to 2^127 (`rem_pio2f`): with the
//! double-precision soft-float routines nothing else on the board needs, over 5 KiB of its
//! 48 KiB of flash. [`sin_cos_f32`]
//! evaluates the same polynomials (libm's `k_sinf` and `k_cosf`, from FreeBSD's k_sinf.c and
//! k_cosf.c: Copyright (C) 1993 by Sun Microsystems, Inc.) after the same reduction (at most
//! one `pi / 2` away, as libm's `sinf` and `cosf` do for `|x| <= 3 pi / 4`) in 64-bit fixed
//! point, whose error (about 2^-62) is far below the double-precision rounding of libm's own
//! evaluation, and rounds the result to `f32` once. Its results are libm's bit for bit on
//! every `f32` of `|x| <= 3 pi / 4` (all 2,150,471,624 of them:
//! `every_f32_up_to_three_quarters_pi`, an ignored test; the regular tests compare the
//! validated face-angle range and a sample of the rest).

/// libm's `k_sinf` coefficients `S1..S4`, magnitudes (`S1 < 0`, `S2 > 0`, `S3 < 0`,
/// `S4 > 0`), from the exact values its source gives in hexadecimal.
const SIN: [u64; 4] = [
    q64(0x0015_5555_54cb_ac77, 55), // -0.166666666416265235595
    q64(0x0011_1110_896e_fbb2, 59), //  0.0083333293858894631756
    q64(0x001a_00f9_e2ca_e774, 65), // -0.000198393348360966317347
    q64(0x0016_cd87_8c3b_46a7, 71), //  0.0000027183114939898219064
];
/// libm's `k_cosf` coefficients `C0..C3`, magnitudes (`C0 < 0`, `C1 > 0`, `C2 < 0`,
/// `C3 > 0`).
const COS: [u64; 4] = [
    q64(0x001f_ffff_fd0c_5e81, 54), // -0.499999997251031003120
    q64(0x0015_5553_e105_3a42, 57), //  0.0416666233237390631894
    q64(0x0016_c087_e80f_1e27, 62), // -0.00138867637746099294692
    q64(0x0019_9342_e0ee_5069, 68), //  0.0000243904487962774090654
];
/// `pi / 2` rounded to double precision (libm's `S1_PIO2`: 0x1921fb54442d18 x 2^-52), in
/// unsigned Q2.62. libm subtracts it from an `f32` in `(pi/4, 3 pi/4]` exactly (Sterbenz),
/// as the integer subtraction below does.
const PIO2_Q62: u64 = 0x0019_21fb_5444_2d18 << 10;

/// `m 2^-e` (below 1) in unsigned Q0.64, truncated.
const fn q64(m: u64, e: u32) -> u64 {
    if e <= 64 {
        m << (64 - e)
    } else {
        m >> (e - 64)
    }
}

/// The high 64 bits of the 128-bit product (fixed-point multiplication, truncated).
#[inline(never)]
fn mul_hi(a: u64, b: u64) -> u64 {
    ((a as u128 * b as u128) >> 64) as u64
}

/// `m 2^(k - 63)` (`m >= 2^63`) rounded to the nearest `f32`, ties to even.
fn to_f32(m: u64, k: i32) -> f32 {
    let mant = (m >> 40) as u32;
    let rem = m & ((1 << 40) - 1);
    let half = 1 << 39;
    let up = (rem > half || (rem == half && mant & 1 == 1)) as u32;
    // mant x 2^(k - 23): its bit 23 adds the 1 to the exponent field (k + 126), and a carry
    // out of the rounding moves it up by one.
    f32::from_bits((((k + 126) as u32) << 23) + mant + up)
}

/// libm's `k_sinf(y)` (`sine`) or `k_cosf(y)` for `0 < y <= pi/4` (Q0.64), both of the form
/// `g (1 - z (c0 - z (c1 - z (c2 - z c3))))` with `z = y^2` (the coefficients' signs
/// alternate), `g = y` for the sine and 1 for the cosine.
#[inline(never)]
fn kernel(y: u64, sine: bool) -> f32 {
    let c = if sine { &SIN } else { &COS };
    let z = mul_hi(y, y);
    let q = c[0] - mul_hi(z, c[1] - mul_hi(z, c[2] - mul_hi(z, c[3])));
    let f = mul_hi(z, q);
    // g = m 2^(k - 63) with m >= 2^63.
    let (m, k) = if sine {
        let l = y.leading_zeros();
        (y << l, -1 - l as i32)
    } else {
        (1 << 63, 0)
    };
    // g (1 - f), f < 1/2: renormalised (one bit at most) before rounding.
    let r = m - mul_hi(m, f);
    if r >> 63 == 0 {
        to_f32(r << 1, k - 1)
    } else {
        to_f32(r, k)
    }
}

/// `(sin x, cos x)` as libm's `sinf` and `cosf` give them, bit for bit, for `|x| <= 3 pi /
/// 4` (exactly: up to `f32::from_bits(0x4016cbe3)`, libm's own bound for that branch); NaN
/// for larger `|x|` and for NaN.
pub fn sin_cos_f32(x: f32) -> (f32, f32) {
    let bits = x.to_bits();
    let ix = bits & 0x7fff_ffff;
    if ix < 0x3980_0000 {
        // |x| < 2^-12: libm returns x and 1.
        return (x, 1.0);
    }
    if ix > 0x4016_cbe3 {
        return (f32::NAN, f32::NAN);
    }
    // |x| = m 2^(e - 23) with e in -12..=1, exactly, in Q2.62.
    let e = (ix >> 23) as i32 - 127;
    let a = u64::from((ix & 0x7f_ffff) | 0x80_0000) << (39 + e);
    let (s, c) = if ix <= 0x3f49_0fda {
        // |x| ~<= pi/4.
        (kernel(a << 2, true), kernel(a << 2, false))
    } else if a > PIO2_Q62 {
        // libm: sin = k_cosf(|x| - pi/2), cos = k_sinf(pi/2 - |x|) < 0 (never 0: a has 24
        // significant bits, PIO2_Q62 53).
        let y = (a - PIO2_Q62) << 2;
        (kernel(y, false), -kernel(y, true))
    } else {
        let y = (PIO2_Q62 - a) << 2;
        (kernel(y, false), kernel(y, true))
    };
    // sinf is odd and cosf even, bit for bit (their kernels are).
    (if bits >> 31 != 0 { -s } else { s }, c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mismatches(bits: impl Iterator<Item = u32>) -> u32 {
        let mut bad = 0;
        for b in bits {
            for x in [f32::from_bits(b), -f32::from_bits(b)] {
                let (s, c) = sin_cos_f32(x);
                if s.to_bits() != libm::sinf(x).to_bits() || c.to_bits() != libm::cosf(x).to_bits()
                {
                    bad += 1;
                }
            }
        }
        bad
    }

    /// Every `f32` from 4 to 86 deg (the validated face angles are 5-85 deg), both signs,
    /// and every 97th value of the rest of `|x| <= 3 pi / 4`: libm's results, bit for bit.
    #[test]
    fn equals_libm_on_the_face_angles_and_a_sample_of_the_rest() {
        let (lo, hi) = (4f32.to_radians().to_bits(), 86f32.to_radians().to_bits());
        assert_eq!(mismatches(lo..=hi), 0);
        assert_eq!(mismatches((0..=0x4016_cbe3).step_by(97)), 0);
        assert_eq!(
            mismatches([0, 0x3980_0000, 0x3f49_0fda, 0x3f49_0fdb, 0x4016_cbe3].into_iter()),
            0
        );
        assert!(sin_cos_f32(f32::from_bits(0x4016_cbe4)).0.is_nan());
        assert!(sin_cos_f32(f32::NAN).1.is_nan());
    }

    /// All 2,150,471,624 `f32` of `|x| <= 3 pi / 4`: about 20 s in a release build
    /// (`cargo test --release -p cta-core --lib trig -- --ignored`).
    #[test]
    #[ignore]
    fn every_f32_up_to_three_quarters_pi() {
        assert_eq!(mismatches(0..=0x4016_cbe3), 0);
    }
}
