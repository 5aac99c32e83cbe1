//! The rows of `trace.csv` (docs/experiments.md) and their hand-over to a sink as soon as no
//! later step writes them.

use std::collections::VecDeque;

/// One row of `trace.csv` (docs/experiments.md): step k and what each party knew at k.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TraceRow {
    /// Step k.
    pub k: u32,
    /// `t = k·T` (s).
    pub t: f64,
    /// Reference position (m).
    pub reference: [f64; 2],
    /// True pose `x(k)`.
    pub pose: [f64; 3],
    /// Measurement `y(k)`.
    pub measurement: [f64; 3],
    /// Clipped nominal `uU(k)` (m/s, rad/s); none at the stop step.
    pub nominal: Option<[f64; 2]>,
    /// `u0D(k)` (rad/s).
    pub u0: Option<[f64; 2]>,
    /// `u1D(k)` (rad/s).
    pub u1: Option<[f64; 2]>,
    /// `b(k)`, applied on `[k, k+1)`.
    pub bit: Option<u8>,
    /// `d̂(k−1)` as `[Δv̂, Δω̂]`.
    pub dhat: Option<[f64; 2]>,
    /// `x̂(k)`.
    pub xhat: Option<[f64; 3]>,
    /// `b̂(k−1)` of the controller.
    pub bhat: Option<u8>,
    /// `b̂(k−1)` of Eve.
    pub bhat_eve: Option<u8>,
    /// Private mode: the ω bit the step's perturbation carries.
    pub bit_omega: Option<u8>,
    /// Private mode: Eve's camera sample `y_e(k)`.
    pub camera: Option<[f64; 3]>,
}

impl TraceRow {
    /// Column names of `trace.csv`.
    pub const COLUMNS: [&'static str; 28] = [
        "k",
        "t",
        "ref_x",
        "ref_y",
        "px",
        "py",
        "theta",
        "meas_x",
        "meas_y",
        "meas_theta",
        "v_nom",
        "omega_nom",
        "u0_r",
        "u0_l",
        "u1_r",
        "u1_l",
        "b",
        "dhat_v",
        "dhat_omega",
        "xhat_x",
        "xhat_y",
        "xhat_theta",
        "bhat",
        "bhat_eve",
        "b_omega",
        "eve_x",
        "eve_y",
        "eve_theta",
    ];
}

/// The rows of a trace still being filled in, between the simulation and its sink. Each
/// step writes its own row and, in private mode, its neighbours (a doublet spans two or three
/// steps and is decided at the sample after it); [`TraceRows::complete_before`] hands over the
/// rows no later step writes.
pub(crate) struct TraceRows<'a> {
    sink: Option<&'a mut dyn FnMut(TraceRow)>,
    /// Rows `first, first + 1, …` not handed over yet.
    open: VecDeque<TraceRow>,
    first: usize,
}

impl<'a> TraceRows<'a> {
    /// Rows for `sink`; none are kept without one.
    pub(crate) fn new(sink: Option<&'a mut dyn FnMut(TraceRow)>) -> Self {
        Self {
            sink,
            open: VecDeque::new(),
            first: 0,
        }
    }

    /// Row `k`, when a trace is recorded.
    ///
    /// # Panics
    /// When row `k` was already handed over (a simulation bug).
    pub(crate) fn row(&mut self, k: usize) -> Option<&mut TraceRow> {
        self.sink.as_ref()?;
        let index = k
            .checked_sub(self.first)
            .expect("a trace row is written after it was handed over");
        if index >= self.open.len() {
            self.open.resize_with(index + 1, TraceRow::default);
        }
        Some(&mut self.open[index])
    }

    /// Hands every row before `k` to the sink.
    pub(crate) fn complete_before(&mut self, k: usize) {
        let Some(sink) = self.sink.as_mut() else {
            return;
        };
        while self.first < k {
            sink(self.open.pop_front().unwrap_or_default());
            self.first += 1;
        }
    }
}

impl Drop for TraceRows<'_> {
    /// The rows still open are complete once the simulation has ended.
    fn drop(&mut self) {
        self.complete_before(self.first + self.open.len());
    }
}
