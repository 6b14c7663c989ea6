//! Plain parameter structs the machines are built from (filled by the `config` crate).

/// Which machine, with its parameters.
#[derive(Debug, Clone, PartialEq)]
pub enum MachineParams {
    Cartesian(CartesianParams),
    Polar(PolarParams),
    Scara(ScaraParams),
    Fivebar(FivebarParams),
}

/// One stepper as configured: its name and travel per microstep (mm, or rad for rotary joints).
#[derive(Debug, Clone, PartialEq)]
pub struct StepperParams {
    pub name: String,
    pub step_distance: f64,
    /// Soft limits in the motor's unit (`position_min`/`position_max`), if configured.
    pub position_min: Option<f64>,
    pub position_max: Option<f64>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct CartesianParams {
    /// `stepper_x`, `stepper_y`, `stepper_z`.
    pub steppers: [StepperParams; 3],
}

#[derive(Debug, Clone, PartialEq)]
pub struct PolarParams {
    /// `stepper_bed` (rad/step), `stepper_arm` (mm/step), `stepper_z`.
    pub bed: StepperParams,
    pub arm: StepperParams,
    pub z: StepperParams,
    /// Where the arm's zero really is, relative to the bed's rotation centre, along the arm (mm).
    /// Zero for an ideal machine. (Centring thesis: `dx`.)
    pub arm_zero_offset: f64,
    /// Sideways offset of the arm's line from the rotation centre (mm). (Centring thesis: `dy`.)
    pub arm_lateral_offset: f64,
}

/// Frame in which SCARA joint angles are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ScaraFrame {
    /// Angles from +X, counter-clockwise (the FEKT-SCARA Klipper module).
    #[default]
    Standard,
    /// X-SCARA / thesis text: angles from +Y, x mirrored.
    XScara,
}

/// Which elbow branch the arm works on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ElbowBranch {
    /// q2 ≥ 0 (the FEKT-SCARA module's `acos` branch).
    #[default]
    Left,
    /// q2 ≤ 0.
    Right,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ScaraParams {
    /// `stepper_a` (shoulder, rad/step), `stepper_b` (elbow motor, rad/step), `stepper_z`.
    pub shoulder_stepper: StepperParams,
    pub elbow_stepper: StepperParams,
    pub z: StepperParams,
    /// Proximal arm (shoulder to elbow), mm.
    pub link1_length: f64,
    /// Distal arm (elbow to nozzle), mm.
    pub link2_length: f64,
    /// Shoulder axis position in bed coordinates, mm.
    pub offset_x: f64,
    pub offset_y: f64,
    /// Elbow coupling `c`: `motor_b = q2 + c·q1` (`ecr` gives `c = 1/ecr`; Morgan `c = 1`; RRF `C` is `−c`).
    pub elbow_coupling: f64,
    /// The FEKT-SCARA `ecr` when the config gave it. When set, `motor_b = q2 + q1/ecr` is computed by
    /// division exactly as the fork does (bit-identical motor positions), and `elbow_coupling` must equal
    /// `1/ecr` (checked to 1e-12). `None`: `elbow_coupling` is used as a multiplier.
    pub ecr: Option<f64>,
    pub elbow: ElbowBranch,
    pub frame: ScaraFrame,
    /// Joint zero offsets (rad): motor angle reading when the joint is at its kinematic zero.
    pub shoulder_zero: f64,
    pub elbow_zero: f64,
    /// Joint limits (rad) on q1 and q2, if configured.
    pub shoulder_limits: Option<(f64, f64)>,
    pub elbow_limits: Option<(f64, f64)>,
    /// Nothing may come closer than this to the shoulder axis (mm); FEKT-SCARA default 60.
    pub base_protection_radius: f64,
    /// Poses with |sin q2| below this are refused as singular (0 disables the check).
    pub singularity_margin: f64,
}

impl StepperParams {
    /// A stepper without soft limits.
    pub fn new(name: &str, step_distance: f64) -> Self {
        StepperParams {
            name: name.into(),
            step_distance,
            position_min: None,
            position_max: None,
        }
    }
}

impl PolarParams {
    /// Klipper's `example-polar.cfg` machine: 16000 microsteps per bed turn, 80 steps/mm arm, 400 steps/mm Z,
    /// no assembly offsets, no soft limits.
    pub fn klipper_example() -> Self {
        PolarParams {
            bed: StepperParams::new("stepper_bed", std::f64::consts::TAU / 16000.0),
            arm: StepperParams::new("stepper_arm", 1.0 / 80.0),
            z: StepperParams::new("stepper_z", 1.0 / 400.0),
            arm_zero_offset: 0.0,
            arm_lateral_offset: 0.0,
        }
    }
}

impl ScaraParams {
    /// The FEKT-SCARA example machine: arms 100/100 mm, elbow crosstalk ratio 3, shoulder at the origin, 60 mm
    /// base protection, 9600 microsteps per joint turn, 400 steps/mm Z, left elbow, no limits or margin.
    pub fn fekt_example() -> Self {
        let joint_step = std::f64::consts::TAU / 9600.0;
        ScaraParams {
            shoulder_stepper: StepperParams::new("stepper_a", joint_step),
            elbow_stepper: StepperParams::new("stepper_b", joint_step),
            z: StepperParams::new("stepper_z", 1.0 / 400.0),
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
            singularity_margin: 0.0,
        }
    }
}

/// Which way a five-bar's joints turn: the sign of the turn `a → b → c` (counter-clockwise positive) that picks one
/// of a circle–circle intersection's two points (RepRapFirmware's `L` workmode, per side and for the distals).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Turn {
    Ccw,
    Cw,
}

impl Turn {
    /// `+1` for counter-clockwise, `−1` for clockwise.
    pub fn sign(self) -> f64 {
        match self {
            Turn::Ccw => 1.0,
            Turn::Cw => -1.0,
        }
    }
}

/// One side of a five-bar: its base joint, links, working mode and motor.
#[derive(Debug, Clone, PartialEq)]
pub struct FivebarArm {
    /// The rotary stepper turning the proximal link (rad/step, limits in rad of motor reading).
    pub stepper: StepperParams,
    /// The base (proximal) joint's axis in bed coordinates, mm.
    pub base: [f64; 2],
    /// Base joint to elbow, mm.
    pub proximal: f64,
    /// Elbow to nozzle, mm.
    pub distal: f64,
    /// The turn base → elbow → nozzle: which of the two elbow positions this side uses.
    pub turn: Turn,
    /// Motor reading (rad) when the proximal link points along +X.
    pub zero: f64,
}

/// A five-bar (parallel) SCARA: two base joints, each turning a proximal link; the distal links meet at the nozzle.
#[derive(Debug, Clone, PartialEq)]
pub struct FivebarParams {
    pub left: FivebarArm,
    pub right: FivebarArm,
    pub z: StepperParams,
    /// The turn left elbow → nozzle → right elbow (RepRapFirmware's forward kinematics: clockwise).
    pub distal_turn: Turn,
    /// Smallest |sin| of each side's proximal–distal angle (serial singularities: the arm straight or folded) and
    /// of the angle between the distal links (the parallel singularity) that a path keeps.
    pub singularity_margin: f64,
}

impl FivebarParams {
    /// The example machine (`examples/machines/fivebar.cfg`): base joints at (−50, 0) and (50, 0), proximal links
    /// 150 mm, distal links 200 mm, elbows outward (left clockwise, right counter-clockwise: RepRapFirmware's
    /// workmode 2), distal turn clockwise, 3200 microsteps per proximal turn ×3 reduction, 400 steps/mm Z,
    /// margin 0.1, no limits.
    pub fn example() -> Self {
        let joint_step = std::f64::consts::TAU / 9600.0;
        let arm = |name: &str, x: f64, turn: Turn| FivebarArm {
            stepper: StepperParams::new(name, joint_step),
            base: [x, 0.0],
            proximal: 150.0,
            distal: 200.0,
            turn,
            zero: 0.0,
        };
        FivebarParams {
            left: arm("stepper_left", -50.0, Turn::Cw),
            right: arm("stepper_right", 50.0, Turn::Ccw),
            z: StepperParams::new("stepper_z", 1.0 / 400.0),
            distal_turn: Turn::Cw,
            singularity_margin: 0.1,
        }
    }
}
