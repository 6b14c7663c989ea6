//! The small comma-separated files calibration reads (logged scans, measured points): `#` comments, blank lines,
//! a header line, then rows of a fixed number of fields, each field with its 1-based column for error messages.

/// A problem at `line`, `column` (1-based); the caller adds the file name.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CsvError {
    pub line: usize,
    pub column: usize,
    pub message: String,
}

/// One data row: its line number and its fields, each with the column where it starts.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Row<'a> {
    pub line: usize,
    pub fields: Vec<(usize, &'a str)>,
}

impl Row<'_> {
    fn error(&self, column: usize, message: String) -> CsvError {
        CsvError {
            line: self.line,
            column,
            message,
        }
    }

    /// Field `index` as a finite number.
    pub fn number(&self, index: usize) -> Result<f64, CsvError> {
        let (column, text) = self.fields[index];
        text.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| self.error(column, format!("`{text}` is not a finite number")))
    }

    /// Field `index` as a number within ±`limit` (`what` names the limit in the message).
    pub fn bounded(&self, index: usize, limit: f64, what: &str) -> Result<f64, CsvError> {
        let v = self.number(index)?;
        if v.abs() <= limit {
            return Ok(v);
        }
        let (column, text) = self.fields[index];
        Err(self.error(
            column,
            format!("`{text}` is beyond {what} (at most ±{limit})"),
        ))
    }

    /// An error pointing at field `index`.
    pub fn error_at(&self, index: usize, message: String) -> CsvError {
        self.error(self.fields[index].0, message)
    }
}

/// The data rows of `text`, after checking that the first row is `header` (case-insensitive) and that every
/// row has as many fields as the header.
pub(crate) fn data_rows<'a>(text: &'a str, header: &[&str]) -> Result<Vec<Row<'a>>, CsvError> {
    let mut rows = Vec::new();
    let mut header_seen = false;
    // A byte-order mark (spreadsheets on Windows write one) is not part of the first field.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    for (i, raw) in text.lines().enumerate() {
        let content = raw.split('#').next().unwrap_or("");
        if content.trim().is_empty() {
            continue;
        }
        let row = Row {
            line: i + 1,
            fields: split_fields(content),
        };
        if row.fields.len() != header.len() {
            return Err(row.error(
                1,
                format!(
                    "expected {} comma-separated columns, found {}",
                    header.len(),
                    row.fields.len()
                ),
            ));
        }
        if header_seen {
            rows.push(row);
            continue;
        }
        for ((column, name), want) in row.fields.iter().zip(header) {
            if !name.eq_ignore_ascii_case(want) {
                return Err(row.error(
                    *column,
                    format!(
                        "header column `{name}` should be `{want}` (header: {})",
                        header.join(",")
                    ),
                ));
            }
        }
        header_seen = true;
    }
    if !header_seen {
        return Err(CsvError {
            line: 1,
            column: 1,
            message: format!("missing header line `{}`", header.join(",")),
        });
    }
    Ok(rows)
}

/// A setting line `key,value` that comes before a file's header (the first line with content), if there is one:
/// its value with the value's line and column, and the text with that line blanked (so the table's line numbers
/// stay the file's). Trailing empty fields are allowed (a spreadsheet pads the line to the table's width).
pub(crate) struct Setting<'a> {
    pub value: &'a str,
    pub line: usize,
    pub column: usize,
}

pub(crate) fn leading_setting<'a>(
    text: &'a str,
    key: &str,
) -> Result<(Option<Setting<'a>>, String), CsvError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let first = text
        .lines()
        .map(|raw| raw.split('#').next().unwrap_or(""))
        .enumerate()
        .find(|(_, c)| !c.trim().is_empty());
    let Some((index, content)) = first else {
        return Ok((None, text.to_string()));
    };
    let fields = split_fields(content);
    if !fields[0].1.eq_ignore_ascii_case(key) {
        return Ok((None, text.to_string()));
    }
    let (column, value) = fields.get(1).copied().unwrap_or((content.len() + 1, ""));
    if let Some((extra_column, extra)) = fields.iter().skip(2).find(|(_, f)| !f.is_empty()) {
        return Err(CsvError {
            line: index + 1,
            column: *extra_column,
            message: format!("the `{key}` line takes one value, found also `{extra}`"),
        });
    }
    let table = text
        .lines()
        .enumerate()
        .map(|(i, l)| if i == index { "" } else { l })
        .collect::<Vec<_>>()
        .join("\n");
    let setting = Setting {
        value,
        line: index + 1,
        column,
    };
    Ok((Some(setting), table))
}

/// Trimmed fields with their 1-based starting columns.
fn split_fields(content: &str) -> Vec<(usize, &str)> {
    let mut fields = Vec::new();
    let mut start = 0;
    for part in content.split(',') {
        let lead = part.len() - part.trim_start().len();
        fields.push((start + lead + 1, part.trim()));
        start += part.len() + 1;
    }
    fields
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_byte_order_mark_is_not_part_of_the_header() {
        let rows = data_rows("\u{feff}magnet,side\n0,near\n", &["magnet", "side"]).expect("reads");
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].fields, vec![(1, "0"), (3, "near")]);
        // A stray one inside is still wrong, and named.
        let e = data_rows("magnet,\u{feff}side\n", &["magnet", "side"]).expect_err("refused");
        assert!(e.message.contains("should be `side`"), "{}", e.message);
    }

    #[test]
    fn rows_keep_their_columns_and_skip_comments() {
        let text = "# log\na, b\n\n1,  2 # note\n";
        let rows = data_rows(text, &["a", "b"]).expect("parses");
        assert_eq!(
            rows,
            vec![Row {
                line: 4,
                fields: vec![(1, "1"), (5, "2")]
            }]
        );
        assert_eq!(rows[0].number(1), Ok(2.0));
    }

    #[test]
    fn wrong_header_width_and_numbers_are_located() {
        let place = |text: &str| {
            data_rows(text, &["a", "b"])
                .err()
                .map(|e| (e.line, e.column))
        };
        assert_eq!(place("a,c\n"), Some((1, 3)));
        assert_eq!(place("a,b\n1\n"), Some((2, 1)));
        assert_eq!(place(""), Some((1, 1)));
        let rows = data_rows("a,b\n1, 2e9\n", &["a", "b"]).expect("parses");
        assert_eq!(rows[0].bounded(0, 10.0, "ten"), Ok(1.0));
        let far = rows[0].bounded(1, 1e6, "a million").expect_err("refused");
        assert_eq!((far.line, far.column), (2, 4));
        assert!(
            far.message.contains("`2e9` is beyond a million"),
            "{}",
            far.message
        );
        let rows = data_rows("a,b\n1,x\n", &["a", "b"]).expect("parses");
        assert_eq!(
            rows[0].number(1).err().map(|e| (e.line, e.column)),
            Some((2, 3))
        );
    }
}
