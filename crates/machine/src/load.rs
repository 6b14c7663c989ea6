//! A machine ready to plan for, from `printer.cfg`, and the options that make a job plan as a given host does.

use std::path::{Path, PathBuf};

use crate::setup::{MachineSetup, SetupError};
use config::{ConfigError, ConfigWarning, MachineConfig};

/// The configuration as read and the machine built from it.
#[derive(Debug)]
pub struct Machine {
    /// Where the configuration was read from, as reports name it.
    pub source: String,
    pub config: MachineConfig,
    pub setup: MachineSetup,
}

/// Why a machine could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error("{}: {source}", .path.display())]
    Setup { path: PathBuf, source: SetupError },
}

/// Something in the configuration worth a word: a value jointspace reads differently than expected (a warning), or
/// a key nothing reads in a section jointspace interprets (an error: Klipper refuses to start on such a file, so a
/// front-end that builds this machine refuses it too).
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigNote {
    pub span: Option<config::Span>,
    pub message: String,
    pub refused: bool,
}

impl Machine {
    /// Read `path` and build the machine; the configuration's warnings and unknown keys as notes.
    pub fn load(path: &Path) -> Result<(Machine, Vec<ConfigNote>), LoadError> {
        let (config, notes) = Machine::read(path)?;
        let machine =
            Machine::from_config(config, &path.display().to_string()).map_err(|source| {
                LoadError::Setup {
                    path: path.to_path_buf(),
                    source,
                }
            })?;
        Ok((machine, notes))
    }

    /// Build the machine from printer.cfg text named `source` (includes already resolved: the fuzz targets, the
    /// plug-in where Klipper has no file).
    pub fn from_text(text: &str, source: &str) -> Result<Machine, LoadError> {
        let config = MachineConfig::from_str(text, source)?;
        Machine::from_config(config, source).map_err(|source_error| LoadError::Setup {
            path: PathBuf::from(source),
            source: source_error,
        })
    }

    /// Read `path`: the configuration and its notes, before the machine is built from it.
    pub fn read(path: &Path) -> Result<(MachineConfig, Vec<ConfigNote>), ConfigError> {
        let config = MachineConfig::load(path)?;
        let notes = notes(&config);
        Ok((config, notes))
    }

    /// The machine of `config`, read from `source`.
    pub fn from_config(config: MachineConfig, source: &str) -> Result<Machine, SetupError> {
        let setup = MachineSetup::from_config(&config)?;
        Ok(Machine {
            source: source.to_string(),
            config,
            setup,
        })
    }

    /// The machine's set-up planning as `options` say (the kinematics shared, not built again).
    pub fn setup_with(&self, options: PlanOptions) -> MachineSetup {
        let mut setup = self.setup.clone();
        options.apply(&mut setup);
        setup
    }
}

fn notes(config: &MachineConfig) -> Vec<ConfigNote> {
    let warnings = config.warnings.iter().map(|w: &ConfigWarning| ConfigNote {
        span: w.span.clone(),
        message: w.message.clone(),
        refused: false,
    });
    let unused = config.unused_keys().into_iter().map(|unused| ConfigNote {
        message: format!(
            "unknown option `{}` in [{}] (a typo?): Klipper refuses to start on it",
            unused.key, unused.section
        ),
        span: Some(unused.span),
        refused: true,
    });
    warnings.chain(unused).collect()
}

/// How a job plans beyond the machine's own configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PlanOptions {
    /// Skip unreachable moves (reported as warnings) instead of stopping at the first.
    pub skip_unreachable: bool,
    /// Reproduce Klipper's batch-mode flushing (`klippy.py -i`).
    pub klipper_batch: bool,
    /// The host whose planning to reproduce.
    pub host: motion::Host,
}

impl PlanOptions {
    pub fn apply(self, setup: &mut MachineSetup) {
        setup.planner.skip_unreachable = self.skip_unreachable;
        setup.planner.klipper_batch_flush = self.klipper_batch;
        setup.planner.behave_as(self.host);
    }
}
