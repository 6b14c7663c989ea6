//! Integration tests of the virtual printer: the acceptance cases (polar sideways arm offset on the
//! corpus circle, SCARA with a wrong ECR and arm length, no assembly error), the motor model against closed
//! forms, the report files, and the five-bar.

mod acceptance;
mod common;
mod fivebar;
mod motor_model;
mod pattern_crosses;
mod report_files;
mod spiral_vase;
