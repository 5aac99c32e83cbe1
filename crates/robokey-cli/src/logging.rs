//! The process's logger: which diagnostic messages of robokey's libraries — RustDDS's and
//! ros2-client's discovery, matching and QoS above all — reach stderr. `--log FILTER`, else
//! `RUST_LOG`, else none: robokey names its own errors, and RustDDS 0.15 logs an ERROR at
//! every exit (`leave_multicast_group`: it leaves on another interface than it joined), which
//! a user should not have to read. The filter is a level (`off`, `error`, `warn`, `info`,
//! `debug`, `trace`) or `TARGET=LEVEL` pairs with an optional default level, e.g.
//! `warn,rustdds=debug` (the `log` crate's messages arrive through `tracing-log`).

use tracing_subscriber::filter::Targets;
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;

use crate::exit::Usage;

/// The filter when neither `--log` nor `RUST_LOG` gives one.
pub const DEFAULT_FILTER: &str = "off";

/// Installs the logger with `flag`'s filter (`--log`), else `RUST_LOG`'s, else
/// [`DEFAULT_FILTER`].
///
/// # Errors
/// The filter does not parse ([`Usage`]: exit 2).
pub fn install(flag: Option<&str>) -> anyhow::Result<()> {
    let environment = std::env::var("RUST_LOG")
        .ok()
        .filter(|f| !f.trim().is_empty());
    let (filter, origin) = match (flag, environment) {
        (Some(filter), _) => (filter.to_owned(), "--log"),
        (None, Some(filter)) => (filter, "RUST_LOG"),
        (None, None) => (DEFAULT_FILTER.to_owned(), "the default filter"),
    };
    let targets: Targets = filter.parse().map_err(|e| {
        Usage(format!(
            "{origin} {filter}: {e} (allowed: a level — off, error, warn, info, debug, trace — \
             or TARGET=LEVEL pairs, e.g. warn,rustdds=debug)"
        ))
    })?;
    // A second logger in one process (only tests could try) keeps the first.
    let _ = tracing_subscriber::registry()
        .with(tracing_subscriber::fmt::layer().with_writer(std::io::stderr))
        .with(targets)
        .try_init();
    Ok(())
}
