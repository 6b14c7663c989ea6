//! sim

pub mod hall;
