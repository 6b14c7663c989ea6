//! Fuzz target `convert`: arbitrary G-code bytes converted for a polar machine (cylindrical output, adaptive
//! segmentation), then the output checked to be free of NaN/inf.
#![no_main]

use std::sync::{Arc, OnceLock};

use convert::{AxisMap, ConvertOptions, Converter, Target, convert_gcode};
use kinematics::Kinematics;
use libfuzzer_sys::fuzz_target;

const MACHINE: &str = include_str!("../../examples/machines/polar.cfg");

fn axis_map() -> &'static AxisMap {
    static MAP: OnceLock<AxisMap> = OnceLock::new();
    MAP.get_or_init(|| {
        let machine = config::MachineConfig::from_str(MACHINE, "examples/machines/polar.cfg")
            .expect("example machine is valid");
        let kin: Arc<dyn Kinematics> =
            Arc::from(kinematics::build(&machine.params).expect("polar kinematics"));
        AxisMap::motors(kin, Target::Cylindrical).expect("polar axis map")
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(mut converter) =
        Converter::new(axis_map().clone(), ConvertOptions::default(), Vec::new())
    else {
        return;
    };
    if convert_gcode(data, "fuzz.gcode", &mut converter).is_err() {
        return;
    }
    if let Ok((out, _stats)) = converter.finish() {
        let text = String::from_utf8_lossy(&out);
        assert!(
            !text.contains("NaN") && !text.contains("inf"),
            "non-finite number in output:\n{text}"
        );
    }
});
