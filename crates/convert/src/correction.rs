//! Centre correction for polar printers whose arm zero is displaced from the bed's rotation centre
//! (centring thesis, part 2): `dx` along the arm, `dy` sideways (the arm's line misses the centre).
//!
//! The motor model is the kinematics crate's [`Polar`] with these offsets (its documentation derives
//! `r = −dx + √(|p|² − dy²)`, bed angle `atan2(p) − atan2(dy, dx + r)`, Klipper's motor sign); points with
//! `|p| < |dy|` never pass under the nozzle and are errors with the line that asks for them.
//! This corrects the *arm* (its zero and its line miss the axis; the part stays where the slicer put it about
//! the axis). The thesis' own correction is another model: it writes the polar coordinates of `p − d`, the
//! part shifted, which corrects a bed whose origin lies at `d` from the axis (`convert --centre-shift`,
//! [`crate::ConvertOptions::translate`]). The two differ even for `dy = 0`: for `p` at 5 mm, 45°, and
//! `d = (2, 0)` the shifted part is 3.855 mm from the axis, the offset arm reaches `p` at 3.000 mm.
//! Two outputs:
//! - [`CentreCorrection::motor_map`]: motor-space G-code for the real (offset) machine;
//! - [`CentreCorrection::cartesian_map`]: Cartesian G-code for a polar firmware that assumes the ideal model,
//!   with XY rewritten so that the motors it computes put the nozzle where the input intended.

use std::sync::Arc;

use kinematics::PolarParams;
use kinematics::polar::Polar;

use crate::axes::AxisMap;
use crate::error::ConvertError;
use crate::options::Target;

/// The measured assembly error of a polar machine (mm).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CentreCorrection {
    /// Where the arm's zero really is, along the arm, relative to the rotation centre (`dx`).
    pub arm_zero_offset: f64,
    /// Sideways offset of the arm's line from the rotation centre (`dy`).
    pub arm_lateral_offset: f64,
}

impl CentreCorrection {
    /// The real machine: `nominal` with this correction's offsets.
    pub fn real_machine(&self, nominal: &PolarParams) -> Result<Polar, ConvertError> {
        let params = PolarParams {
            arm_zero_offset: self.arm_zero_offset,
            arm_lateral_offset: self.arm_lateral_offset,
            ..nominal.clone()
        };
        Polar::new(params).map_err(|e| ConvertError::Setup(e.to_string()))
    }

    /// The ideal machine the firmware assumes (`nominal` without offsets).
    pub fn ideal_machine(nominal: &PolarParams) -> Result<Polar, ConvertError> {
        CentreCorrection::default().real_machine(nominal)
    }

    /// Output axes for motor-space G-code on the real machine.
    pub fn motor_map(
        &self,
        nominal: &PolarParams,
        target: Target,
    ) -> Result<AxisMap, ConvertError> {
        AxisMap::motors(Arc::new(self.real_machine(nominal)?), target)
    }

    /// Output axes for Cartesian G-code sent to a firmware with the ideal model.
    pub fn cartesian_map(&self, nominal: &PolarParams) -> Result<AxisMap, ConvertError> {
        let real = Arc::new(self.real_machine(nominal)?);
        let ideal = Arc::new(Self::ideal_machine(nominal)?);
        AxisMap::corrected(real, ideal)
    }
}
