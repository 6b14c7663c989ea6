//! Modal interpreter: turns lexed lines into [`Command`](crate::Command)s with Klipper's
//! `gcode_move` semantics (G90/G91, M82/M83, G92 offsets, M220/M221 factors, G20/G21 units, arcs
//! kept whole).
//!
//! State is machine coordinates (`last_position`) plus G92 offsets (`base_position`); the G-code-space
//! position is `last − base` (E divided by the extrude factor, as Klipper reports it).
//! G20 (inches) scales every length the line gives: X Y Z E, I J R and F. The interpreter never
//! guesses where homing leaves the toolhead: the caller tells it with [`Interpreter::set_position`].
//!
//! `state.rs` holds the state and the modal arithmetic both paths share; `general.rs` interprets
//! lexed lines, `fast.rs` reads the commonest lines straight from the bytes, `arcs.rs` holds arc
//! geometry, and `commands.rs` streams a reader's lines through them. Each uses only `state.rs`
//! and `arcs.rs` besides other crate modules (`commands.rs` also the two paths), so the modules
//! form no loop.

mod arcs;
mod commands;
mod fast;
mod general;
mod state;
#[cfg(test)]
mod tests;

pub use arcs::MAX_ARC_TURNS;
pub use commands::Commands;
pub(crate) use fast::FastSink;
pub use state::{CommandSet, Interpreter, InterpreterOptions};
