//! Regenerates the reconciliation table of docs/postprocessing.md: for each error rate Q and
//! block size n, LDPC and Cascade side by side on synthetic blocks — the leak's efficiency
//! against the soft limit, f_soft = leak_EC / Σᵢ h₂(1/(1 + e^{|Lᵢ|})), and against the hard one,
//! f_hard = leak_EC / (n · h₂(Q)), the block failure rate, and the time per block.
//!
//! The controller's LLRs come from a binary symmetric channel (`bsc`: Lᵢ = ±ln((1 − Q)/Q)) or a
//! binary-input Gaussian channel (`awgn`: yᵢ = ±1 + N(0, σ²), Lᵢ = 2yᵢ/σ², σ set so that the
//! hard decisions err with probability Q). Cascade sees only hard decisions and the true Q.
//!
//! ```text
//! cargo run --release -p robokey-secrecy --example reconciliation_table -- \
//!     --channel awgn --n 100000 --blocks 1000 --q 0.005,0.0078,0.02,0.05,0.1,0.2,0.3
//! ```
//! Options: `--channel bsc|awgn`, `--n BITS`, `--blocks COUNT`, `--q LIST`,
//! `--efficiency F` and `--finite-length C` (LDPC's first syndrome, m = ⌈F·H + C·√H⌉ for
//! the soft limit H), `--iterations CAP` (the last round's), `--round-iterations CAP` (the
//! rounds' before it), `--feedback ROUNDS` (LDPC feedback
//! rounds at most), `--increment SHARE` (of m per feedback round), `--method
//! ldpc|cascade|both`, `--seed S`. Columns: `undet` counts wrong blocks the decoder took for
//! right (only the tags catch them); `rounds` is LDPC's mean rounds (Cascade's: its mean
//! question messages); `iter` LDPC's mean belief-propagation iterations over all rounds.

use std::time::Instant;

use rand::rngs::ChaCha8Rng;
use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, Normal};
use robokey_secrecy::ldpc::{LdpcSettings, reconcile, soft_limit_bits};
use robokey_secrecy::{BitString, Cascade, Reconciler, binary_entropy};

struct Options {
    channel: String,
    n: usize,
    blocks: usize,
    rates: Vec<f64>,
    settings: LdpcSettings,
    method: String,
    seed: u64,
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
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let [key, value] = pair else {
            return Err(format!("option {} needs a value", pair[0]));
        };
        let bad = |e: &dyn std::fmt::Display| format!("{key} {value}: {e}");
        match key.as_str() {
            "--channel" if value == "bsc" || value == "awgn" => options.channel = value.clone(),
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
            "{:7} {:>8} {:>7.4} {:>7.5} {:>7.5} {:>8} {:>6} {:>6} {:>8.4} {:>7.4} {:>7.4} {:>7.2} {:>6.1} {:>9.1}",
            method,
            options.n,
            q,
            errors / (b * options.n as f64),
            self.soft / (b * options.n as f64),
            self.blocks,
            self.failures,
            self.undetected,
            self.failures as f64 / b,
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
    println!(
        "# channel {}, LDPC {}, seed {}",
        options.channel,
        options.settings.agreement_term(),
        options.seed
    );
    println!(
        "{:7} {:>8} {:>7} {:>7} {:>7} {:>8} {:>6} {:>6} {:>8} {:>7} {:>7} {:>7} {:>6} {:>9}",
        "method",
        "n",
        "Q",
        "Q_real",
        "H(X|L)",
        "blocks",
        "fail",
        "undet",
        "FER",
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
            let hard_limit = options.n as f64 * binary_entropy(q);
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
                let out = Cascade::biconf(q).and_then(|c| c.reconcile(&x, &hard, &mut rng));
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
