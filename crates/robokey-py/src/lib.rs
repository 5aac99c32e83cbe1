//! robokey from Python: the native module `robokey._native` behind the `robokey` package
//! (python/robokey, docs/python.md). It calls the library's own functions — configuration,
//! simulation, sweeps, secrecy, a camera's threat, the eavesdroppers, the folder, capture and key store readers — and hands results to
//! Python column by column; the package turns them into Arrow tables and numpy arrays.

mod columns;
mod config;
mod errors;
mod eve;
mod readers;
mod recorded;
mod run;
mod secrecy;
mod sweep;
mod threat;

use pyo3::prelude::*;

/// The native half of the `robokey` package; use `robokey`, not this module.
#[pymodule]
mod _native {
    use pyo3::prelude::*;

    #[pymodule_export]
    use crate::errors::{ConfigError, InputError, OptionError, SimulationError, SweepError};
    #[pymodule_export]
    use crate::eve::eve;
    #[pymodule_export]
    use crate::readers::{read_sweep, read_trace};
    #[pymodule_export]
    use crate::recorded::{list_keys, read_capture};
    #[pymodule_export]
    use crate::run::run;
    #[pymodule_export]
    use crate::secrecy::secrecy;
    #[pymodule_export]
    use crate::sweep::sweep;
    #[pymodule_export]
    use crate::threat::threat;

    /// The version (the crate's and the git commit it was built from), the metrics' units and
    /// the world presets' names.
    #[pymodule_init]
    fn init(module: &Bound<'_, PyModule>) -> PyResult<()> {
        module.add("__version__", robokey_lab::VERSION)?;
        module.add("METRIC_UNITS", crate::columns::metric_units(module.py())?)?;
        let presets: Vec<&str> = robokey::world::WorldPreset::ALL
            .iter()
            .map(|p| p.name())
            .collect();
        module.add("WORLD_PRESETS", presets)?;
        Ok(())
    }
}
