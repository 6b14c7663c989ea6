//! The reader benchmark's work, shared by the criterion bench and the `reader_profile` example.

use gcode::{Commands, Reader, file_stats};

/// Lex every line; the number of words (so the work cannot be optimised away).
pub fn lex_only(data: &[u8]) -> usize {
    let mut reader = Reader::new(data, "bench");
    let mut words = 0;
    while let Some(line) = reader.next_line() {
        if let Ok(line) = line {
            words += line.words().len();
        }
    }
    words
}

/// Lex and interpret every line; the number of commands.
pub fn lex_and_interpret(data: &[u8]) -> usize {
    Commands::from_reader(data, "bench")
        .filter(Result::is_ok)
        .count()
}

/// Lex, interpret and summarise every line as `jointspace stats` does; the number of lines (beside
/// [`lex_and_interpret`] it shows what the statistics cost beyond the reading).
pub fn lex_interpret_and_stats(data: &[u8]) -> u64 {
    file_stats(data, "bench").map_or(0, |stats| stats.lines)
}
