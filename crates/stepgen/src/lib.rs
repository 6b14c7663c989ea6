//! stepgen
