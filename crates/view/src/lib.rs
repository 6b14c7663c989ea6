//! One job: a planned print job turned into one self-contained HTML page (`jointspace view`). The print is
//! planned once, by the estimate ([`printjob::estimate_watched`]): its numbers are the page's numbers, and its
//! planning pass hands every planned move here, where each move's motors are followed and the limit that holds it is
//! named ([`motors`]), layers are cut and merged for display ([`collect`], [`decimate`]), the motors are put against
//! time ([`series`]), and the machine's workspace map goes under the part ([`map`]). [`page`] writes the HTML.

pub mod collect;
pub mod decimate;
mod encode;
pub mod map;
pub mod motors;
pub mod page;
pub mod series;

use std::sync::Arc;

use machine::{Machine, PlanOptions};
use printjob::{Estimate, EstimateError, Reopen};
use serde::Serialize;

pub use collect::Budget;
pub use page::{PageMeta, write_page};

/// A motor as the page names it.
#[derive(Debug, Clone, Serialize)]
pub struct MotorName {
    pub name: String,
    /// `mm` or `rad`.
    pub unit: &'static str,
}

/// What the page shows beside the estimate's numbers.
#[derive(Debug, Clone)]
pub struct View {
    pub machine: &'static str,
    pub motors: Vec<MotorName>,
    pub limits: motors::Limits,
    pub collected: collect::Collected,
    /// The workspace map, or why the machine has none.
    pub map: Result<map::MapData, String>,
}

impl Budget {
    /// Enough for a sharp picture of a large print in a page of a few tens of megabytes at most.
    pub const DEFAULT: Budget = Budget {
        tolerance: 0.02,
        per_layer: 40_000,
        total: 400_000,
        series: 20_000,
    };
}

/// Plan the stream of `open` on `machine` as the estimate plans it (refused moves are shown, not fatal: the plan
/// goes on from where the machine stays) and gather the page's data.
pub fn plan(
    machine: &Machine,
    options: PlanOptions,
    open: Reopen<'_>,
    name: &str,
    budget: Budget,
) -> Result<(Estimate, View), EstimateError> {
    let options = PlanOptions {
        skip_unreachable: true,
        ..options
    };
    let setup = machine.setup_with(options);
    let kin = Arc::clone(&setup.kinematics);
    let step_rates: Vec<Option<f64>> = kin
        .motors()
        .iter()
        .map(|m| {
            machine
                .config
                .max_step_rate(&m.name)
                .map(|r| r * m.step_distance)
        })
        .collect();
    let kinematic_limits = setup.planner.kinematic_limits.clone();
    let limits = motors::Limits::new(kin.as_ref(), &kinematic_limits, &step_rates);
    let mut probe = motors::MotorProbe::new(Arc::clone(&kin), kinematic_limits);
    if let Some(home) = setup.home_position {
        probe.place(home);
    }
    let max_velocity = setup.planner.limits.max_velocity;
    let scales = decimate::Scales {
        speed: max_velocity,
        ..Default::default()
    };
    let (mut reader, mut collector) = collect::collector(probe, max_velocity, budget, scales);
    let estimate = printjob::estimate_watched(
        machine,
        options,
        open,
        name,
        &|_| false,
        &mut collector,
        &mut reader,
    )?;
    let motors = kin
        .motors()
        .iter()
        .map(|m| MotorName {
            name: m.name.clone(),
            unit: match m.unit {
                kinematics::MotorUnit::Mm => "mm",
                kinematics::MotorUnit::Rad => "rad",
            },
        })
        .take(decimate::MOTORS)
        .collect();
    let view = View {
        machine: kin.name(),
        motors,
        limits,
        collected: collector.finish(),
        map: map::map(&machine.config.params),
    };
    Ok((estimate, view))
}
