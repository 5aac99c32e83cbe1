//! Regenerates the reconciliation table of docs/postprocessing.md: for each error rate Q and
//! block size n, LDPC and Cascade side by side on synthetic blocks — the leak's efficiency
//! against the soft limit, f_soft = leak_EC / Σᵢ h₂(1/(1 + e^{|Lᵢ|})), and against the hard one,
//! f_hard = leak_EC / (n · h₂(Q)), the block failure rate, and the time per block.
//!
//! The controller's LLRs come from a binary symmetric channel (`bsc`: Lᵢ = ±ln((1 − Q)/Q)) or a
//! binary-input Gaussian channel (`awgn`: yᵢ = ±1 + N(0, σ²), Lᵢ = 2yᵢ/σ², σ set so that the
//! hard decisions err with probability Q), or a slice of a multilevel symbol (`slice`, below).
//! Cascade sees only hard decisions and the true Q (for a slice, the block's realised rate).
//!
//! **Slices.** `--channel slice --levels L --slice j --scale k [--labeling natural|gray]`: the
//! robot's label b is uniform on 0..L; the symbol's amplitude is k·(L − 1 − 2i)/√E, i the
//! label's amplitude index (natural i = b, Gray i = gray⁻¹(b)), E = (L² − 1)/3 (the binary
//! alphabet's power, as `protocol.levels` keeps Δ's); the controller sees y = amplitude +
//! N(0, σ²) with σ the binary channel's at Q (so Q names the binary doublet's error rate at
//! the same Δ, k the multiple of Δ). The block's bits are bit j of each label, and the
//! controller's LLRs are the staged ones multistage reconciliation decodes with, as
//! `robokey::private::likelihood::staged_llrs` computes them: the label's lower bits (slices
//! < j, reconciled earlier) known, its higher ones marginalised,
//! Lᵢ = ln Σ_{b: b_j = 0, b_{<j} = known} e^{−(y − a_b)²/2σ²} − ln Σ_{b: b_j = 1, …} (same).
//! It is the one-dimensional, straight-path idealisation of a doublet's symbol (the
//! separation along the Mahalanobis direction; a turn's residual and the other dimension
//! ignored). `f_hard` then uses the block's realised error rate.
//!
//! ```text
//! cargo run --release -p robokey-secrecy --example reconciliation_table -- \
//!     --channel awgn --n 100000 --blocks 1000 --q 0.005,0.0078,0.02,0.05,0.1,0.2,0.3
//! ```
//! Options: `--channel bsc|awgn`, `--n BITS`, `--blocks COUNT`, `--q LIST`,
//! `--levels`, `--slice`, `--scale`, `--labeling` (slices only), `--efficiency F` and `--finite-length C` (LDPC's first syndrome, m = ⌈F·H + C·√H⌉ for
//! the soft limit H), `--iterations CAP` (the last round's), `--round-iterations CAP` (the
//! rounds' before it), `--feedback ROUNDS` (LDPC feedback
//! rounds at most), `--increment SHARE` (of m per feedback round), `--method
//! ldpc|cascade|both`, `--seed S`. Columns: `undet` counts wrong blocks the decoder took for
//! right (only the tags catch them); `FER95` the failure rate's one-sided 95 % Clopper–Pearson
//! upper bound; `rounds` is LDPC's mean rounds (Cascade's: its mean
//! question messages); `iter` LDPC's mean belief-propagation iterations over all rounds.

use std::time::Instant;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use robokey_secrecy::interval::clopper_pearson_upper;
use robokey_secrecy::ldpc::{LdpcSettings, reconcile, soft_limit_bits};
use robokey_secrecy::special::ln_add_exp;
use robokey_secrecy::{BitString, Cascade, Reconciler, binary_entropy};

/// A slice of a multilevel symbol (see the module docs).
#[derive(Clone, Copy)]
struct Slice {
    /// Amplitude levels L: 2, 4 or 8.
    levels: usize,
    /// The label bit j this block carries (0: the fine slice, decoded first).
    bit: usize,
    /// The multiple k of the binary Δ.
    scale: f64,
    /// Gray labeling instead of natural.
    gray: bool,
}

impl Slice {
    /// Label b's amplitude k·(L − 1 − 2i)/√E.
    fn amplitude(&self, label: usize) -> f64 {
        let levels = self.levels as f64;
        let index = if self.gray {
            (1..usize::BITS).fold(label, |index, shift| index ^ (label >> shift))
        } else {
            label
        };
        self.scale * (levels - 1.0 - 2.0 * index as f64) / ((levels * levels - 1.0) / 3.0).sqrt()
    }

    /// The staged LLR of bit j of `label` from the observation y: lower bits known, higher
    /// ones marginalised.
    fn llr(&self, label: usize, y: f64, sigma: f64) -> f64 {
        let lower = (1 << self.bit) - 1;
        let ln_sum = |value: usize| {
            (0..self.levels)
                .filter(|b| (b >> self.bit) & 1 == value && b & lower == label & lower)
                .map(|b| -(y - self.amplitude(b)).powi(2) / (2.0 * sigma * sigma))
                .fold(f64::NEG_INFINITY, ln_add_exp)
        };
        ln_sum(0) - ln_sum(1)
    }
}

struct Options {
    channel: String,
    n: usize,
    blocks: usize,
    rates: Vec<f64>,
    settings: LdpcSettings,
    method: String,
    seed: u64,
    slice: Slice,
}

fn parse() -> Result<Options, String> {
    let mut options = Options {
        channel: "awgn".into(),
        n: 100_000,
        blocks: 100,
        rates: vec![0.005, 0.0078, 0.02, 0.05, 0.1, 0.2, 0.3],
        settings: LdpcSettings::DEFAULT,
        method: "both".into(),
        seed: 1,
        slice: Slice {
            levels: 4,
            bit: 0,
            scale: 1.0,
            gray: false,
        },
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let [key, value] = pair else {
            return Err(format!("option {} needs a value", pair[0]));
        };
        let bad = |e: &dyn std::fmt::Display| format!("{key} {value}: {e}");
        match key.as_str() {
            "--channel" if ["bsc", "awgn", "slice"].contains(&value.as_str()) => {
                options.channel = value.clone();
            }
            "--levels" if ["2", "4", "8"].contains(&value.as_str()) => {
                options.slice.levels = value.parse().map_err(|e| bad(&e))?;
            }
            "--slice" => options.slice.bit = value.parse().map_err(|e| bad(&e))?,
            "--scale" => options.slice.scale = value.parse().map_err(|e| bad(&e))?,
            "--labeling" if value == "natural" || value == "gray" => {
                options.slice.gray = value == "gray";
            }
            "--n" => options.n = value.parse().map_err(|e| bad(&e))?,
            "--blocks" => options.blocks = value.parse().map_err(|e| bad(&e))?,
            "--q" => {
                options.rates = value
                    .split(',')
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|e| bad(&e))?;
            }
            "--efficiency" => {
                options.settings.efficiency = value.parse().map_err(|e| bad(&e))?;
            }
            "--finite-length" => {
                options.settings.finite_length = value.parse().map_err(|e| bad(&e))?;
            }
            "--feedback" => {
                options.settings.feedback_rounds = value.parse().map_err(|e| bad(&e))?;
            }
            "--increment" => {
                options.settings.increment = value.parse().map_err(|e| bad(&e))?;
            }
            "--iterations" => {
                options.settings.max_iterations = value.parse().map_err(|e| bad(&e))?;
            }
            "--round-iterations" => {
                options.settings.round_iterations = value.parse().map_err(|e| bad(&e))?;
            }
            "--method" if ["ldpc", "cascade", "both"].contains(&value.as_str()) => {
                options.method = value.clone();
            }
            "--seed" => options.seed = value.parse().map_err(|e| bad(&e))?,
            _ => return Err(format!("unknown option or value: {key} {value}")),
        }
    }
    let slice = options.slice;
    if slice.bit >= slice.levels.trailing_zeros() as usize {
        return Err(format!(
            "--slice {} outside 0..{} for --levels {}",
            slice.bit,
            slice.levels.trailing_zeros(),
            slice.levels
        ));
    }
    if !(slice.scale.is_finite() && slice.scale > 0.0) {
        return Err(format!("--scale {} must be a positive number", slice.scale));
    }
    Ok(options)
}

/// Φ(−1/σ) = Q by bisection on σ, with Φ from erfc (Abramowitz–Stegun 7.1.26, |error| < 1.5·10⁻⁷).
fn sigma_for(q: f64) -> f64 {
    let upper_tail = |z: f64| {
        let x = z / std::f64::consts::SQRT_2;
        let t = 1.0 / (1.0 + 0.327_591_1 * x);
        let poly = t
            * (0.254_829_592
                + t * (-0.284_496_736
                    + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
        0.5 * poly * (-x * x).exp()
    };
    let (mut low, mut high) = (1e-3, 100.0);
    for _ in 0..100 {
        let mid = 0.5 * (low + high);
        if upper_tail(1.0 / mid) < q {
            low = mid;
        } else {
            high = mid;
        }
    }
    0.5 * (low + high)
}

/// The robot's bits, the controller's LLRs, and its hard decisions.
fn block(options: &Options, q: f64, rng: &mut ChaCha8Rng) -> (BitString, Vec<f64>, BitString) {
    let x = BitString::random(options.n, rng);
    if options.channel == "slice" {
        return slice_block(options, q, rng);
    }
    let llrs: Vec<f64> = if options.channel == "bsc" {
        let l = ((1.0 - q) / q).ln();
        (0..options.n)
            .map(|i| {
                let y = x.get(i).unwrap_or(false) ^ (rng.random::<f64>() < q);
                if y { -l } else { l }
            })
            .collect()
    } else {
        let sigma = sigma_for(q);
        let noise = Normal::new(0.0, sigma).expect("σ > 0");
        (0..options.n)
            .map(|i| {
                let s = if x.get(i).unwrap_or(false) { -1.0 } else { 1.0 };
                2.0 * (s + noise.sample(rng)) / (sigma * sigma)
            })
            .collect()
    };
    let hard: Vec<bool> = llrs.iter().map(|&l| l < 0.0).collect();
    (x, llrs, BitString::from_bools(&hard))
}

/// A block of one slice: bit j of uniform labels, and the staged LLRs of their symbols seen
/// through N(0, σ²), σ the binary channel's at `q`.
fn slice_block(
    options: &Options,
    q: f64,
    rng: &mut ChaCha8Rng,
) -> (BitString, Vec<f64>, BitString) {
    let slice = options.slice;
    let sigma = sigma_for(q);
    let noise = Normal::new(0.0, sigma).expect("σ > 0");
    let (bits, llrs): (Vec<bool>, Vec<f64>) = (0..options.n)
        .map(|_| {
            let label = rng.random_range(0..slice.levels);
            let y = slice.amplitude(label) + noise.sample(rng);
            ((label >> slice.bit) & 1 == 1, slice.llr(label, y, sigma))
        })
        .unzip();
    let hard: Vec<bool> = llrs.iter().map(|&l| l < 0.0).collect();
    (
        BitString::from_bools(&bits),
        llrs,
        BitString::from_bools(&hard),
    )
}

#[derive(Default)]
struct Tally {
    blocks: usize,
    failures: usize,
    /// Failures the decoder did not notice (only the tags catch them).
    undetected: usize,
    leak: f64,
    soft: f64,
    hard: f64,
    iterations: f64,
    rounds: f64,
    seconds: f64,
}

impl Tally {
    fn row(&self, method: &str, options: &Options, q: f64, errors: f64) {
        let b = self.blocks.max(1) as f64;
        println!(
            "{:7} {:>8} {:>7.4} {:>7.5} {:>7.5} {:>8} {:>6} {:>6} {:>8.4} {:>8.4} {:>7.4} {:>7.4} {:>7.2} {:>6.1} {:>9.1}",
            method,
            options.n,
            q,
            errors / (b * options.n as f64),
            self.soft / (b * options.n as f64),
            self.blocks,
            self.failures,
            self.undetected,
            self.failures as f64 / b,
            clopper_pearson_upper(self.failures as u64, self.blocks as u64, 0.05).unwrap_or(1.0),
            self.leak / self.soft,
            self.leak / self.hard,
            self.rounds / b,
            self.iterations / b,
            1e3 * self.seconds / b,
        );
    }
}

fn main() {
    let options = match parse() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let channel = if options.channel == "slice" {
        let s = options.slice;
        format!(
            "slice {} of {}-level {} labels at {}×Δ",
            s.bit,
            s.levels,
            if s.gray { "gray" } else { "natural" },
            s.scale
        )
    } else {
        options.channel.clone()
    };
    println!(
        "# channel {channel}, LDPC {}, seed {}",
        options.settings.agreement_term(),
        options.seed
    );
    println!(
        "{:7} {:>8} {:>7} {:>7} {:>7} {:>8} {:>6} {:>6} {:>8} {:>8} {:>7} {:>7} {:>7} {:>6} {:>9}",
        "method",
        "n",
        "Q",
        "Q_real",
        "H(X|L)",
        "blocks",
        "fail",
        "undet",
        "FER",
        "FER95",
        "f_soft",
        "f_hard",
        "rounds",
        "iter",
        "ms/block"
    );
    for (k, &q) in options.rates.iter().enumerate() {
        let mut rng = ChaCha8Rng::seed_from_u64(options.seed ^ ((k as u64) << 32));
        let (mut ldpc, mut cascade) = (Tally::default(), Tally::default());
        let mut errors = 0.0;
        for _ in 0..options.blocks {
            let (x, llrs, hard) = block(&options, q, &mut rng);
            let wrong = x.hamming_distance(&hard).unwrap_or(0) as f64;
            errors += wrong;
            let soft = soft_limit_bits(&llrs);
            // A slice's error rate is the block's own; the binary channels' is Q.
            let rate = if options.channel == "slice" {
                (wrong / options.n as f64).clamp(1e-9, 0.5)
            } else {
                q
            };
            let hard_limit = options.n as f64 * binary_entropy(rate);
            if options.method != "cascade" {
                let seed: [u8; 32] = rng.random();
                let start = Instant::now();
                match reconcile(&x, &llrs, options.settings, seed) {
                    Ok(out) => {
                        ldpc.seconds += start.elapsed().as_secs_f64();
                        ldpc.blocks += 1;
                        ldpc.failures += usize::from(out.corrected != x);
                        ldpc.undetected += usize::from(out.converged && out.corrected != x);
                        ldpc.leak += out.leak as f64;
                        ldpc.iterations += f64::from(out.iterations);
                        ldpc.rounds += f64::from(out.rounds);
                    }
                    Err(e) => {
                        eprintln!("LDPC at Q = {q}: {e}");
                        return;
                    }
                }
                ldpc.soft += soft;
                ldpc.hard += hard_limit;
            }
            if options.method != "ldpc" {
                let start = Instant::now();
                let out = Cascade::biconf(rate).and_then(|c| c.reconcile(&x, &hard, &mut rng));
                cascade.seconds += start.elapsed().as_secs_f64();
                cascade.blocks += 1;
                match out {
                    Ok(out) => {
                        cascade.failures += usize::from(out.corrected != x);
                        cascade.undetected += usize::from(out.corrected != x);
                        cascade.leak += out.leak as f64;
                        cascade.rounds += f64::from(out.messages);
                    }
                    Err(_) => cascade.failures += 1,
                }
                cascade.soft += soft;
                cascade.hard += hard_limit;
            }
        }
        if options.method != "cascade" {
            ldpc.row("ldpc", &options, q, errors);
        }
        if options.method != "ldpc" {
            cascade.row("cascade", &options, q, errors);
        }
    }
}
