//! Private-sensing configurations and the bits of their simulated sessions, for the
//! statistical tests (each test binary that declares this module uses all of it).

use robokey::Config;
use robokey::private::DoubletBit;
use robokey::sim::simulate;

/// The default configuration in private sensing, with `extra` TOML appended.
pub fn private(extra: &str) -> Config {
    Config::from_toml(&format!("[sensing]\nmode = \"private\"\n{extra}"), "test").unwrap()
}

/// Every bit of replicates `0..sessions` of `config`.
pub fn bits(config: &Config, sessions: u32) -> Vec<DoubletBit> {
    (0..sessions)
        .flat_map(|r| simulate(config, r, false).unwrap().private.unwrap().bits)
        .collect()
}
