//! G-code reader and writer for jointspace.
//!
//! - [`Reader`]: streaming, zero-copy lexer over any `BufRead` (spans, `N` numbers, checksums,
//!   `;`/`( )` comments, raw-text parameters, Klipper extended commands, exact numbers).
//! - [`Interpreter`] / [`Commands`]: modal interpreter with Klipper's `gcode_move` semantics, yielding
//!   [`Spanned`]`<`[`Command`]`>` (moves in machine coordinates, mm and mm/s).
//! - [`Writer`]: fixed-decimal or exact G-code output.
//! - [`stats`]: streaming file summary.
//!
//! ```
//! use gcode::{Command, Commands};
//! let mut commands = Commands::from_reader(&b"G1 X10 F600\n"[..], "example.gcode");
//! let first = commands.next_command().unwrap().unwrap();
//! assert!(matches!(first.value, Command::Move(m) if m.target[0] == 10.0 && m.feed == 10.0));
//! ```

pub mod command;
pub mod error;
pub mod interp;
pub mod lexer;
pub mod meta;
pub mod number;
pub mod reader;
pub mod stats;
#[cfg(test)]
mod test_input;
pub mod writer;

pub use command::{AccelParams, Arc, Command, Meta, Move, Position, Span, Spanned, VelocityLimit};
pub use error::{ErrorKind, GcodeError, Warning, WarningKind, Warnings};
pub use interp::{CommandSet, Commands, Interpreter, InterpreterOptions};
pub use lexer::{CommandWord, Comment, ExtParam, Line, Word};
pub use reader::{Reader, ReaderOptions};
pub use stats::{Stats, StatsCollector, file_stats};
pub use writer::{Decimals, NumberFormat, Writer, WriterOptions, format_number};
