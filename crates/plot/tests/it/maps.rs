//! Real workspace maps (polar and SCARA from the golden configs) written as pictures.

use std::f64::consts::TAU;

use kinematics::workspace::map_machine;
use kinematics::{ElbowBranch, MachineParams, PolarParams, ScaraFrame, ScaraParams, StepperParams};

use crate::glue::workspace_data;
use crate::wellformed::check_xml;

fn stepper(name: &str, step: f64, max: Option<f64>) -> StepperParams {
    StepperParams {
        name: name.into(),
        step_distance: step,
        position_min: None,
        position_max: max,
    }
}

pub fn polar() -> MachineParams {
    MachineParams::Polar(PolarParams {
        bed: stepper("stepper_bed", TAU / 16000.0, None),
        arm: stepper("stepper_arm", 1.0 / 80.0, Some(300.0)),
        z: stepper("stepper_z", 0.0025, Some(200.0)),
        arm_zero_offset: 0.0,
        arm_lateral_offset: 0.0,
    })
}

pub fn scara() -> MachineParams {
    MachineParams::Scara(ScaraParams {
        shoulder_stepper: stepper("stepper_a", TAU / 9600.0, None),
        elbow_stepper: stepper("stepper_b", TAU / 9600.0, None),
        z: stepper("stepper_z", 0.0025, Some(200.0)),
        link1_length: 100.0,
        link2_length: 100.0,
        offset_x: 0.0,
        offset_y: 0.0,
        elbow_coupling: 1.0 / 3.0,
        ecr: Some(3.0),
        elbow: ElbowBranch::Left,
        frame: ScaraFrame::Standard,
        shoulder_zero: 0.0,
        elbow_zero: 0.0,
        shoulder_limits: None,
        elbow_limits: None,
        base_protection_radius: 60.0,
        singularity_margin: 0.05,
    })
}

#[test]
fn workspace_maps_write_every_picture() {
    let dir = tempfile::tempdir().expect("tempdir");
    for (stem, params) in [("polar", polar()), ("scara", scara())] {
        let map = map_machine(&params, 10.0, 1.0).expect("map");
        let data = workspace_data(&map);
        let written =
            plot::workspace::write_workspace_maps(&data, dir.path(), stem).expect("pictures");
        // reach + two motors + machine, each PNG and SVG.
        assert_eq!(written.len(), 8);
        for path in &written {
            let name = path
                .file_name()
                .expect("file name")
                .to_string_lossy()
                .into_owned();
            assert!(name.starts_with(stem), "{name}");
            if name.ends_with(".svg") {
                check_xml(&std::fs::read_to_string(path).expect("svg")).expect("well-formed");
            } else {
                let decoder = png::Decoder::new(std::fs::File::open(path).expect("png"));
                let info = decoder.read_info().expect("png header").info().clone();
                assert_eq!((info.width, info.height), (900, 800));
            }
        }
        assert!(dir.path().join(format!("{stem}-reach.png")).is_file());
        assert!(dir.path().join(format!("{stem}-machine.svg")).is_file());
    }
}
