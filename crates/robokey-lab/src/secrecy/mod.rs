//! How many of the agreed bits are secret, and against whom (docs/secrecy.md): per grid
//! point and adversary, error rates with exact intervals, plug-in informations with
//! bootstrap intervals, Eve on the accepted bits, the acceptance-independence test,
//! per-position error rates, and the finite-key output length of the post-processing the
//! agents run ([`pipeline`]) over pooled blocks of whole sessions.
//!
//! Sessions are re-simulated from the sweep's `config.resolved.toml` and seeds; sessions are
//! added (replicates 0, 1, …) until the pooled raw key fills the requested number of blocks.
//! In odometry mode each session is simulated once and every adversary hears its transcript
//! ([`crate::run::sessions`]); a learning adversary (identify, transcript) hears them in
//! order, so what she learned from earlier sessions serves her on later ones.
//!
//! This module computes; the stage ([`stage`]) writes the results into the sweep folder
//! (`secrecy.json`, `private-map.json`) and reads them back, and [`crate::report::secrecy`]
//! renders them.

pub mod analyze;
pub mod map;
pub mod options;
pub mod pipeline;
pub mod point;
pub mod private;
pub mod rate_map;
pub mod request;
pub mod stage;
pub mod table;

pub use analyze::{analyze, analyze_with};
pub use options::{
    LlrModel, MAX_SESSIONS, Reconciliation, SecrecyOptions, Sizing, default_adversaries,
    default_max_sessions,
};
pub use pipeline::{Block, BlockSettings, Pooling};
pub use point::{AdversaryClass, PointSecrecy, PositionErrors, Rate, holds_against};
pub use private::PrivateFigures;
pub use request::{OptionError, RequestOption, SecrecyRequest};
pub use stage::Secrecy;
