//! The eavesdropping stage: a campaign computed once and written into its folder as
//! `campaign.json` — the sessions' configuration, every campaign's runs, and campaign 0's
//! decided periods at full precision — then read back by reports, which render it without
//! simulating anything.

use std::path::{Path, PathBuf};

use robokey::Config;
use serde::{Deserialize, Serialize};

use super::campaign::{Campaign, StrategyRun};
use super::period::PeriodRecord;
use crate::error::{LabError, io_at};
use crate::output::{read_json, write};

/// The file of a campaign.
pub const CAMPAIGN_JSON: &str = "campaign.json";

/// `campaign.json`.
#[derive(Serialize, Deserialize)]
struct CampaignFile {
    /// The sessions' configuration.
    config: Config,
    /// Periods of one session.
    steps_per_session: u32,
    /// Every campaign's runs, campaign-major, strategies in order, without their periods.
    runs: Vec<StrategyRun>,
    /// Campaign 0's decided periods, per strategy.
    periods: Vec<Vec<PeriodRecord>>,
}

impl Campaign {
    /// Writes `campaign.json` into `dir`; returns the file.
    ///
    /// # Errors
    /// The file cannot be written.
    pub fn write(&self, dir: &Path) -> Result<PathBuf, LabError> {
        std::fs::create_dir_all(dir).map_err(io_at(dir))?;
        let file = CampaignFile {
            config: self.config.clone(),
            steps_per_session: self.steps_per_session,
            runs: self.all.clone(),
            periods: self.runs.iter().map(|r| r.periods.clone()).collect(),
        };
        let json = serde_json::to_string(&file).expect("JSON serializes") + "\n";
        write(&dir.join(CAMPAIGN_JSON), json)
    }

    /// Reads the campaign [`Campaign::write`] wrote into `dir`.
    ///
    /// # Errors
    /// The file is missing or does not read back: not JSON of a campaign, an invalid
    /// configuration, more strategies' periods than campaign 0 has runs.
    pub fn read(dir: &Path) -> Result<Self, LabError> {
        let path = dir.join(CAMPAIGN_JSON);
        let file: CampaignFile = read_json(&path)?;
        let malformed = |message: String| LabError::Malformed {
            place: path.display().to_string(),
            message,
        };
        file.config
            .validate()
            .map_err(|e| malformed(e.to_string()))?;
        if file.periods.len() > file.runs.len() {
            return Err(malformed(format!(
                "periods of {} strategies, runs of {}",
                file.periods.len(),
                file.runs.len()
            )));
        }
        let runs = file
            .runs
            .iter()
            .zip(file.periods)
            .map(|(run, periods)| StrategyRun {
                periods,
                ..run.clone()
            })
            .collect();
        Ok(Self {
            config: file.config,
            runs,
            all: file.runs,
            steps_per_session: file.steps_per_session,
        })
    }
}

#[cfg(test)]
mod tests {
    use robokey::config::EveStrategy;

    use super::*;
    use crate::adversary::run_campaigns;

    #[test]
    fn a_campaign_reads_back_exactly() {
        let dir = std::env::temp_dir().join(format!("robokey-campaign-{}", std::process::id()));
        let mut config = Config::default();
        config.eve.sessions = 2;
        let strategies = [EveStrategy::Mismatch, EveStrategy::Identify];
        let campaign = run_campaigns(&config, &strategies, 2).unwrap();
        assert!(campaign.runs.iter().all(|r| !r.periods.is_empty()));
        campaign.write(&dir).unwrap();
        assert_eq!(Campaign::read(&dir).unwrap(), campaign);
        std::fs::write(dir.join(CAMPAIGN_JSON), "{}").unwrap();
        let err = Campaign::read(&dir).unwrap_err().to_string();
        assert!(err.contains("campaign.json: missing field"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
