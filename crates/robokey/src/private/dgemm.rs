//! The products `nalgebra` hands to `matrixmultiply`'s `dgemm`, computed here with each
//! element rounded as the kernel `matrixmultiply` picks on this CPU rounds it.
//!
//! `matrixmultiply` (0.3, `dgemm_kernel::detect`) chooses its kernel at run time: AVX-512
//! where `avx512f` is detected, else AVX2 with FMA where `fma` and `avx2` are, else AVX, else a
//! portable one. Every kernel packs `A` and `B` into panels and keeps one accumulator per
//! element of `C = A·B`, from `+0` over `k` ascending (in blocks of [`KC`] terms), and stores
//! `α·acc` with `α = 1` (exact) where `nalgebra`'s `mul_to` calls it with `β = 0`:
//!
//! - the AVX-512 and AVX2 kernels fuse: `acc = fma(a_ik, b_kj, acc)`, one rounding per term;
//! - the AVX and portable kernels do not: `acc = a_ik·b_kj + acc`, the product and the sum
//!   each rounded.
//!
//! [`Accumulation::of`] makes the same choice (and honours `matrixmultiply`'s compile-time
//! `MMTEST_FEATURE` list, which restricts the features its detection may see, the same way).
//! The fused chain needs the FMA instruction: `f64::mul_add` in code compiled without the
//! `fma` target feature is a library call per term. So the fused kernel runs inside `pulp`'s
//! x86-64-v3 token (AVX2, FMA, BMI1/2, …, detected at run time), whose `vectorize` compiles it
//! with those features in a function of its own (the `unsafe` is `pulp`'s), four rows per
//! vector and four columns at a time. A CPU whose `matrixmultiply` fuses but that lacks one of
//! x86-64-v3's other features, an inner dimension above [`KC`] (where `matrixmultiply` adds
//! the blocks' sums), and other architectures keep `nalgebra`'s product.

use std::sync::OnceLock;

#[cfg(target_arch = "x86_64")]
use pulp::{Simd, f64x4, x86::V3};

/// `matrixmultiply`'s `KC` for `f64`: the terms of an element summed in one chain; a longer
/// inner dimension is summed in blocks whose chains are then added.
pub const KC: usize = 256;

/// Rows per vector of the fused kernel.
#[cfg(target_arch = "x86_64")]
const LANES: usize = 4;

/// How this CPU's `matrixmultiply` kernel accumulates an element, with what computes it here.
#[derive(Clone, Copy, Debug)]
pub enum Accumulation {
    /// `acc = fma(a_ik, b_kj, acc)` from `+0`, `k` ascending, run with the FMA instruction.
    #[cfg(target_arch = "x86_64")]
    Fused(V3),
    /// `acc = a_ik·b_kj + acc` from `+0`, `k` ascending.
    Plain,
}

impl Accumulation {
    /// The accumulation of a product with inner dimension `k`, `None` where `nalgebra`'s
    /// product is kept (see the module's documentation).
    #[must_use]
    pub fn of(k: usize) -> Option<Self> {
        static DETECTED: OnceLock<Option<Accumulation>> = OnceLock::new();
        if k > KC {
            return None;
        }
        *DETECTED.get_or_init(detect)
    }

    /// `out = a·b` over column-major slices (`a` is `m × k`, `b` is `k × n`, `out` is
    /// `m × n`), each element this accumulation's chain.
    ///
    /// # Panics
    ///
    /// If the slices' lengths do not match the shapes.
    pub fn product_to(self, a: &[f64], m: usize, k: usize, b: &[f64], out: &mut [f64]) {
        assert!(
            a.len() == m * k
                && m > 0
                && k > 0
                && b.len().is_multiple_of(k)
                && out.len() == m * (b.len() / k),
            "product of {m}×{k} ({} elements) and {} elements into {}",
            a.len(),
            b.len(),
            out.len()
        );
        match self {
            #[cfg(target_arch = "x86_64")]
            Self::Fused(simd) => simd.vectorize(FusedProduct {
                simd,
                a,
                m,
                k,
                b,
                out,
            }),
            Self::Plain => plain_product(a, m, k, b, out),
        }
    }
}

/// `matrixmultiply`'s choice of kernel on this CPU, as the accumulation computed here.
#[cfg(target_arch = "x86_64")]
fn detect() -> Option<Accumulation> {
    let avx512f = allowed("avx512f") && std::arch::is_x86_feature_detected!("avx512f");
    let fma = allowed("fma") && std::arch::is_x86_feature_detected!("fma");
    let avx2 = allowed("avx2") && std::arch::is_x86_feature_detected!("avx2");
    if avx512f || (fma && avx2) {
        V3::try_new().map(Accumulation::Fused)
    } else {
        Some(Accumulation::Plain)
    }
}

/// Elsewhere `matrixmultiply` has other kernels (NEON's fuses): `nalgebra`'s product is kept.
#[cfg(not(target_arch = "x86_64"))]
fn detect() -> Option<Accumulation> {
    None
}

/// Whether `matrixmultiply`'s detection may see `feature`: all of them, unless its crate was
/// compiled with `MMTEST_FEATURE` set to a comma-separated list (its own testing switch, read
/// by both crates when they are compiled, so they agree).
#[cfg(target_arch = "x86_64")]
fn allowed(feature: &str) -> bool {
    match option_env!("MMTEST_FEATURE") {
        None | Some("") => true,
        Some(list) => list.split(',').any(|f| f == feature),
    }
}

/// The unfused chain over column-major slices: each element `+0`, then `a_ik·b_kj +` it for
/// `k = 0, 1, …` (written `acc += a_ik·b_kj`: a rounded sum is the same either way round).
fn plain_product(a: &[f64], m: usize, k: usize, b: &[f64], out: &mut [f64]) {
    for (c, bc) in out.chunks_exact_mut(m).zip(b.chunks_exact(k)) {
        c.fill(0.0);
        for (ac, &x) in a.chunks_exact(m).zip(bc) {
            for (y, &p) in c.iter_mut().zip(ac) {
                *y += p * x;
            }
        }
    }
}

/// The fused product's operands, run by `pulp` in a function compiled for x86-64-v3.
#[cfg(target_arch = "x86_64")]
struct FusedProduct<'a> {
    simd: V3,
    a: &'a [f64],
    m: usize,
    k: usize,
    b: &'a [f64],
    out: &'a mut [f64],
}

#[cfg(target_arch = "x86_64")]
impl pulp::NullaryFnOnce for FusedProduct<'_> {
    type Output = ();

    /// Four columns of `out` at a time, then the one to three left.
    #[inline(always)]
    fn call(self) {
        let Self {
            simd,
            a,
            m,
            k,
            b,
            out,
        } = self;
        let n = out.len() / m;
        let full = n - n % 4;
        let (out, out_rest) = out.split_at_mut(full * m);
        let (b, b_rest) = b.split_at(full * k);
        for (c, bc) in out.chunks_exact_mut(4 * m).zip(b.chunks_exact(4 * k)) {
            fused_columns::<4>(simd, a, m, k, bc, c);
        }
        match n - full {
            1 => fused_columns::<1>(simd, a, m, k, b_rest, out_rest),
            2 => fused_columns::<2>(simd, a, m, k, b_rest, out_rest),
            3 => fused_columns::<3>(simd, a, m, k, b_rest, out_rest),
            _ => {}
        }
    }
}

/// `N` columns of `out = a·b` (`b` is `k × N`, `out` is `m × N`): for each block of four
/// rows, `N` vector accumulators from `+0`, each term `acc = fma(a_ik, b_kj, acc)` lane by
/// lane (a block's missing rows are zeros, their lanes discarded).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn fused_columns<const N: usize>(
    simd: V3,
    a: &[f64],
    m: usize,
    k: usize,
    b: &[f64],
    out: &mut [f64],
) {
    let mut row = 0;
    while row < m {
        let rows = LANES.min(m - row);
        let mut acc = [simd.splat_f64s(0.0); N];
        for (p, column) in a.chunks_exact(m).enumerate() {
            let x = lanes(&column[row..row + rows]);
            for (c, sum) in acc.iter_mut().enumerate() {
                *sum = simd.mul_add_e_f64s(x, simd.splat_f64s(b[c * k + p]), *sum);
            }
        }
        for (c, sum) in acc.into_iter().enumerate() {
            let f64x4(v0, v1, v2, v3) = sum;
            let column = &mut out[c * m + row..c * m + row + rows];
            if let Ok(block) = <&mut [f64; LANES]>::try_from(&mut *column) {
                *block = [v0, v1, v2, v3];
            } else {
                for (y, v) in column.iter_mut().zip([v0, v1, v2]) {
                    *y = v;
                }
            }
        }
        row += LANES;
    }
}

/// The first four values of `x` as a vector, zeros where it has fewer.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn lanes(x: &[f64]) -> f64x4 {
    match *x {
        [v0, v1, v2, v3, ..] => f64x4(v0, v1, v2, v3),
        [v0, v1, v2] => f64x4(v0, v1, v2, 0.0),
        [v0, v1] => f64x4(v0, v1, 0.0, 0.0),
        [v0] => f64x4(v0, 0.0, 0.0, 0.0),
        [] => f64x4(0.0, 0.0, 0.0, 0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::private::product::tests::value;
    use nalgebra::DMatrix;
    use rand::{RngExt, SeedableRng};

    fn random(rng: &mut rand::rngs::ChaCha8Rng, rows: usize, columns: usize) -> DMatrix<f64> {
        DMatrix::from_fn(rows, columns, |_, _| value(rng))
    }

    fn same(x: &DMatrix<f64>, y: &DMatrix<f64>) -> bool {
        x.shape() == y.shape() && x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
    }

    /// `a·b` by the accumulation this CPU's `matrixmultiply` uses.
    fn dispatched(accumulation: Accumulation, a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = DMatrix::from_element(a.nrows(), b.ncols(), f64::NAN);
        accumulation.product_to(
            a.as_slice(),
            a.nrows(),
            a.ncols(),
            b.as_slice(),
            out.as_mut_slice(),
        );
        out
    }

    fn nalgebras(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
        let mut out = DMatrix::from_element(a.nrows(), b.ncols(), f64::NAN);
        a.mul_to(b, &mut out);
        out
    }

    /// Every shape on `nalgebra`'s `dgemm` path up to 14 × 14 × 14 (four products each), then
    /// 400 random shapes up to 64 × 64 × 64, bit for bit (signed zeros included) against
    /// `nalgebra`, i.e. `matrixmultiply`'s kernel on this CPU (the AVX2 or AVX-512 one where
    /// FMA is detected; the AVX or portable one when built with `MMTEST_FEATURE=avx` or
    /// `MMTEST_FEATURE=sse2`).
    #[test]
    fn every_dgemm_shape_is_matrixmultiplys_bit_for_bit() {
        let Some(accumulation) = Accumulation::of(KC) else {
            eprintln!("this CPU's matrixmultiply kernel is left to nalgebra: nothing to compare");
            return;
        };
        eprintln!("accumulation: {accumulation:?}");
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(31);
        let small =
            (6..=14).flat_map(|m| (6..=14).flat_map(move |k| (6..=14).map(move |n| (m, k, n))));
        let shapes: Vec<(usize, usize, usize)> = small
            .flat_map(|shape| [shape; 4])
            .chain((0..400).map(|_| {
                let mut d = || rng.random_range(6..=64);
                (d(), d(), d())
            }))
            .collect();
        for (m, k, n) in shapes {
            let (a, b) = (random(&mut rng, m, k), random(&mut rng, k, n));
            let (expected, got) = (nalgebras(&a, &b), dispatched(accumulation, &a, &b));
            assert!(same(&expected, &got), "{m}×{k}×{n}: {expected} vs {got}");
        }
    }

    /// The fused kernel against the chain written with `f64::mul_add`, every shape up to
    /// 9 × 9 × 9 (the row blocks' and column groups' remainders, and shapes below the
    /// `dgemm` threshold): exact whatever `matrixmultiply` does.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_fused_kernel_is_the_fma_chain() {
        let Some(simd) = V3::try_new() else {
            eprintln!("no x86-64-v3 on this CPU: the fused kernel cannot run");
            return;
        };
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(32);
        for m in 1..=9 {
            for k in 1..=9 {
                for n in 0..=9 {
                    let (a, b) = (random(&mut rng, m, k), random(&mut rng, k, n));
                    let expected = DMatrix::from_fn(m, n, |i, j| {
                        (0..k).fold(0.0, |acc: f64, p| a[(i, p)].mul_add(b[(p, j)], acc))
                    });
                    let mut got = DMatrix::from_element(m, n, f64::NAN);
                    Accumulation::Fused(simd).product_to(
                        a.as_slice(),
                        m,
                        k,
                        b.as_slice(),
                        got.as_mut_slice(),
                    );
                    assert!(same(&expected, &got), "{m}×{k}×{n}: {expected} vs {got}");
                }
            }
        }
    }

    /// The two chains round differently on these values, so the comparison with `nalgebra`
    /// above tells them apart: on this CPU exactly one of them is `matrixmultiply`'s.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_chains_differ_and_one_is_matrixmultiplys() {
        let mut rng = rand::rngs::ChaCha8Rng::seed_from_u64(33);
        let (a, b) = (random(&mut rng, 13, 13), random(&mut rng, 13, 13));
        let expected = nalgebras(&a, &b);
        let mut plain = DMatrix::from_element(13, 13, f64::NAN);
        Accumulation::Plain.product_to(a.as_slice(), 13, 13, b.as_slice(), plain.as_mut_slice());
        let fused = DMatrix::from_fn(13, 13, |i, j| {
            (0..13).fold(0.0, |acc: f64, p| a[(i, p)].mul_add(b[(p, j)], acc))
        });
        assert!(!same(&plain, &fused));
        assert!(same(&plain, &expected) != same(&fused, &expected));
        let fuses = matches!(Accumulation::of(13), Some(Accumulation::Fused(_)));
        assert_eq!(same(&fused, &expected), fuses);
    }
}
