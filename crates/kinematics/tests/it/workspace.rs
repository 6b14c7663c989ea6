//! Workspace maps against closed-form areas and resolutions.

use std::f64::consts::PI;

use kinematics::workspace::{self, Outline};
use kinematics::{MachineParams, ScaraParams};

use crate::machines::{fekt_params, polar_params};

#[test]
fn polar_map_covers_the_bed_disc() {
    let params = MachineParams::Polar(polar_params(0.0, 0.0));
    let map = workspace::map_machine(&params, 2.0, 1.0).expect("map");
    assert_eq!(
        map.outline,
        Outline::Circle {
            centre: [0.0, 0.0],
            radius: 300.0
        }
    );
    let disc = PI * 300.0 * 300.0;
    let area = map.summary.reachable_area_mm2;
    assert!((area - disc).abs() / disc < 0.01, "area {area} vs {disc}");
    // Arm: 1/80 mm per step everywhere; bed: r·2π/16000, largest at the rim.
    let arm = map.summary.per_motor[1].expect("reachable cells");
    assert!((arm.min.value - 0.0125).abs() < 1e-12 && (arm.max.value - 0.0125).abs() < 1e-12);
    let bed = map.summary.per_motor[0].expect("reachable cells");
    let rim = 300.0 * 2.0 * PI / 16000.0;
    assert!(
        bed.max.value <= rim && bed.max.value > rim * 0.99,
        "{}",
        bed.max.value
    );
    let r = (bed.max.at[0].powi(2) + bed.max.at[1].powi(2)).sqrt();
    assert!(r > 297.0, "worst bed resolution at r = {r}");
    // The machine's worst case is the worse of the two (orthogonal rows).
    let machine = map.summary.machine.expect("reachable");
    assert!((machine.max.value - bed.max.value).abs() < 1e-12);
}

#[test]
fn scara_map_area_is_the_annulus_between_base_and_reach() {
    let params = ScaraParams {
        base_protection_radius: 60.0,
        ..fekt_params()
    };
    let map = workspace::map_machine(&MachineParams::Scara(params), 1.0, 1.0).expect("map");
    let annulus = PI * (200.0f64.powi(2) - 60.0f64.powi(2));
    let area = map.summary.reachable_area_mm2;
    assert!(
        (area - annulus).abs() / annulus < 0.01,
        "area {area} vs {annulus}"
    );
    // Worst case at the straight arm: the nozzle moves tangentially by (L1 + L2)·δq1 + L2·δq2 with
    // δq1 = δa, δq2 = δb − δa/3, i.e. (200 − 100/3)·δa + 100·δb; the worst unit step vector gives
    // √(166.67² + 100²)·step.
    let machine = map.summary.machine.expect("reachable");
    let step = 2.0 * PI / 9600.0;
    let expected = ((200.0f64 - 100.0 / 3.0).powi(2) + 100.0f64.powi(2)).sqrt() * step;
    assert!(
        machine.max.value <= expected * (1.0 + 1e-9),
        "{} vs {expected}",
        machine.max.value
    );
    assert!(
        machine.max.value > expected * 0.99,
        "{} vs {expected}",
        machine.max.value
    );
    let at = machine.max.at;
    assert!(
        (at[0] * at[0] + at[1] * at[1]).sqrt() > 195.0,
        "worst case at {at:?}"
    );
}
