//! Integration tests of the converter: corpus round trips on polar and SCARA machines, the fixed
//! segmentation comparison, closed-form cases and the centre correction.

mod cases;
mod common;
mod corpus;
mod correction;
mod limits;
mod machines;
mod modes;
