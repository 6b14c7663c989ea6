//! One pass of the reader benchmark's work over the corpus, for `valgrind --tool=callgrind`
//! (instruction counts are repeatable where wall-clock time is not):
//! `reader_profile lex|interpret FILE...`.

use gcode::{Commands, Reader};

fn main() {
    let mut args = std::env::args().skip(1);
    let mode = args.next().unwrap_or_default();
    let mut data = Vec::new();
    for path in args {
        data.extend(std::fs::read(&path).unwrap_or_default());
        data.push(b'\n');
    }
    let count = match mode.as_str() {
        "lex" => {
            let mut reader = Reader::new(&data[..], "profile");
            let mut words = 0;
            while let Some(line) = reader.next_line() {
                if let Ok(line) = line {
                    words += line.words().len();
                }
            }
            words
        }
        _ => Commands::from_reader(&data[..], "profile")
            .filter(Result::is_ok)
            .count(),
    };
    println!("{} bytes, {count}", data.len());
}
