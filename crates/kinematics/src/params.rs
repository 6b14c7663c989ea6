//! Plain parameter structs the machines are built from (filled by the `config` crate).

/// Which machine, with its parameters.
#[derive(Debug, Clone, PartialEq)]
pub enum MachineParams {
    Cartesian(CartesianParams),
    Polar(PolarParams),
    Scara(ScaraParams),
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
