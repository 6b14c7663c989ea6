//! Integration tests of stepgen: Klipper golden step files, closed-form cases and properties.

mod closed_form;
mod golden;
mod machines;
mod properties;
mod scara_exact;
