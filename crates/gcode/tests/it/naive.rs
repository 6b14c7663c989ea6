//! A deliberately simple, independent G-code scan (split on whitespace, std's float parser) used to
//! check the real lexer and interpreter on the corpus.

/// One code line as the naive scan sees it: upper-case command and `(letter, value)` words.
#[derive(Debug, Clone, PartialEq)]
pub struct NaiveLine {
    pub command: String,
    pub words: Vec<(char, f64)>,
}

/// Raw-text commands whose parameters are not numeric words.
const RAW_TEXT: [&str; 4] = ["M117", "M486", "M862", "M115"];

/// Code lines of `text` (comments stripped at `;`); `None` for lines without code.
pub fn scan(text: &str) -> Vec<Option<NaiveLine>> {
    text.lines().map(scan_line).collect()
}

fn scan_line(line: &str) -> Option<NaiveLine> {
    let code = line.split(';').next().unwrap_or("");
    let mut tokens = code.split_whitespace();
    let command = tokens.next()?.to_ascii_uppercase();
    let base = command.split('.').next().unwrap_or("");
    let mut words = Vec::new();
    if !RAW_TEXT.contains(&base) && !command.contains('_') {
        for token in tokens {
            let mut chars = token.chars();
            let letter = chars.next().map(|c| c.to_ascii_uppercase()).unwrap_or(' ');
            let rest = chars.as_str();
            if rest.is_empty() {
                continue;
            }
            let value: f64 = rest
                .parse()
                .unwrap_or_else(|_| panic!("naive scan cannot read {token:?} in {line:?}"));
            words.push((letter, value));
        }
    }
    Some(NaiveLine { command, words })
}

/// Is this the command `name` (`G1` also matches `G01`)?
pub fn is(line: &NaiveLine, name: &str) -> bool {
    let trimmed = |s: &str| {
        let (letter, digits) = s.split_at(1);
        format!("{letter}{}", digits.trim_start_matches('0'))
    };
    line.command.len() > 1 && trimmed(&line.command) == trimmed(name)
}

/// The G-code-space E at the end of the file, by replaying M82/M83/G90/G91/G92 E and E words.
pub fn final_e(lines: &[Option<NaiveLine>]) -> f64 {
    let (mut relative_coord, mut relative_extrude) = (false, false);
    let mut e = 0.0;
    for line in lines.iter().flatten() {
        let e_word = line
            .words
            .iter()
            .rev()
            .find(|(l, _)| *l == 'E')
            .map(|(_, v)| *v);
        if is(line, "M83") || is(line, "M82") {
            relative_extrude = is(line, "M83");
        } else if is(line, "G91") || is(line, "G90") {
            relative_coord = is(line, "G91");
        } else if is(line, "G92") {
            if line.words.is_empty() {
                e = 0.0;
            } else if let Some(v) = e_word {
                e = v;
            }
        } else if let Some(v) =
            e_word.filter(|_| ["G0", "G1", "G2", "G3"].iter().any(|n| is(line, n)))
        {
            e = if relative_coord || relative_extrude {
                e + v
            } else {
                v
            };
        }
    }
    e
}
