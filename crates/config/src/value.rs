//! Typed accessors on a [`Section`], like Klipper's `getfloat`/`getint`/`getboolean`/`getchoice`/
//! `getlists`, with errors that point at the offending value. Every accessor marks its key as read.

use std::fmt;

use crate::document::{Entry, Section};
use crate::error::ConfigError;
use crate::span::Span;

/// Range checks in Klipper's style: `min`/`max` are inclusive, `above`/`below` exclusive.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Bounds {
    pub min: Option<f64>,
    pub max: Option<f64>,
    pub above: Option<f64>,
    pub below: Option<f64>,
}

impl Bounds {
    /// No limits.
    pub const NONE: Bounds = Bounds {
        min: None,
        max: None,
        above: None,
        below: None,
    };

    pub fn min(self, value: f64) -> Bounds {
        Bounds {
            min: Some(value),
            ..self
        }
    }

    pub fn max(self, value: f64) -> Bounds {
        Bounds {
            max: Some(value),
            ..self
        }
    }

    pub fn above(self, value: f64) -> Bounds {
        Bounds {
            above: Some(value),
            ..self
        }
    }

    pub fn below(self, value: f64) -> Bounds {
        Bounds {
            below: Some(value),
            ..self
        }
    }

    /// `Err(message)` when `value` breaks a bound (messages worded like Klipper's).
    pub fn check(&self, value: f64) -> Result<(), String> {
        if let Some(min) = self.min.filter(|m| value < *m) {
            return Err(format!("must have minimum of {min}"));
        }
        if let Some(max) = self.max.filter(|m| value > *m) {
            return Err(format!("must have maximum of {max}"));
        }
        if let Some(above) = self.above.filter(|a| value <= *a) {
            return Err(format!("must be above {above}"));
        }
        if let Some(below) = self.below.filter(|b| value >= *b) {
            return Err(format!("must be below {below}"));
        }
        Ok(())
    }
}

/// Pull resistor requested on an input pin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pull {
    #[default]
    None,
    /// `^`
    Up,
    /// `~`
    Down,
}

/// A pin description like `!PF1`, `^PJ1`, `~!PA2` or `probe:z_virtual_endstop`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Pin {
    /// Chip prefix before `:` (None means the main `mcu`).
    pub chip: Option<String>,
    pub name: String,
    /// `!`: the signal is inverted.
    pub inverted: bool,
    pub pull: Pull,
}

impl fmt::Display for Pin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.pull {
            Pull::None => {}
            Pull::Up => f.write_str("^")?,
            Pull::Down => f.write_str("~")?,
        }
        if self.inverted {
            f.write_str("!")?;
        }
        if let Some(chip) = &self.chip {
            write!(f, "{chip}:")?;
        }
        f.write_str(&self.name)
    }
}

/// Parses a pin description in Klipper's order: pull (`^`/`~`), then `!`, then `[chip:]name`.
pub fn parse_pin(text: &str, allow_pull: bool) -> Result<Pin, String> {
    let mut rest = text.trim();
    let mut pull = Pull::None;
    if let Some(r) = rest.strip_prefix('^') {
        pull = Pull::Up;
        rest = r.trim_start();
    } else if let Some(r) = rest.strip_prefix('~') {
        pull = Pull::Down;
        rest = r.trim_start();
    }
    if pull != Pull::None && !allow_pull {
        return Err("a pull-up/pull-down ('^'/'~') is not allowed on this pin".to_string());
    }
    let inverted = rest.starts_with('!');
    if inverted {
        rest = rest[1..].trim_start();
    }
    let (chip, name) = match rest.split_once(':') {
        Some((chip, name)) => (Some(chip.trim().to_string()), name.trim()),
        None => (None, rest),
    };
    let bad_name = name.is_empty()
        || name.contains(['^', '~', '!', ':'])
        || name.contains(char::is_whitespace);
    let bad_chip = chip
        .as_deref()
        .is_some_and(|c| c.is_empty() || c.contains(char::is_whitespace));
    if bad_name || bad_chip {
        return Err(format!(
            "invalid pin description '{}' (format: [^~][!][chip:]pin)",
            text.trim()
        ));
    }
    Ok(Pin {
        chip,
        name: name.to_string(),
        inverted,
        pull,
    })
}

/// Parses a finite f64 (Klipper accepts `nan`/`inf`; a NaN limit would poison every later computation).
pub fn parse_f64(text: &str) -> Result<f64, String> {
    let trimmed = text.trim();
    match trimmed.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("'{trimmed}' is not a finite number")),
        Err(_) => Err(format!("expected a number, found '{trimmed}'")),
    }
}

/// Parses Klipper's booleans: true/false, yes/no, on/off, 1/0 (any case).
pub fn parse_bool(text: &str) -> Result<bool, String> {
    match text.trim().to_lowercase().as_str() {
        "true" | "yes" | "on" | "1" => Ok(true),
        "false" | "no" | "off" | "0" => Ok(false),
        other => Err(format!("expected True or False, found '{other}'")),
    }
}

/// `(byte offset, text)` of each non-empty trimmed part of `text` split at any of `separators`.
fn split_parts<'a>(
    text: &'a str,
    separators: &'a [char],
) -> impl Iterator<Item = (usize, &'a str)> + 'a {
    let base = text.as_ptr() as usize;
    text.split(separators).filter_map(move |part| {
        let trimmed = part.trim();
        let offset = trimmed.as_ptr() as usize - base;
        (!trimmed.is_empty()).then_some((offset, trimmed))
    })
}

impl Section {
    /// Builds the error for `entry` with the whole value underlined.
    fn invalid(&self, entry: &Entry, message: impl Into<String>) -> ConfigError {
        self.invalid_at(entry, entry.value_span().clone(), message)
    }

    fn invalid_at(&self, entry: &Entry, span: Span, message: impl Into<String>) -> ConfigError {
        ConfigError::InvalidValue {
            span: Box::new(span),
            section: self.name.clone(),
            key: entry.key.clone(),
            message: message.into(),
        }
    }

    /// Error for a required key that is absent, pointing at the section header.
    pub fn missing(&self, key: &str) -> ConfigError {
        ConfigError::MissingKey {
            span: Box::new(self.header.clone()),
            section: self.name.clone(),
            key: key.to_lowercase(),
        }
    }

    /// An error about a present key, pointing at its value (for checks across several keys).
    pub fn error_at(&self, key: &str, message: impl Into<String>) -> ConfigError {
        match self.entry(key) {
            Some(entry) => self.invalid(entry, message),
            None => ConfigError::InvalidSection {
                span: Box::new(self.header.clone()),
                section: self.name.clone(),
                message: message.into(),
            },
        }
    }

    /// Applies `parse` to the entry if present.
    fn parse_opt<T>(
        &self,
        key: &str,
        parse: impl FnOnce(&Entry) -> Result<T, ConfigError>,
    ) -> Result<Option<T>, ConfigError> {
        self.entry(key).map(parse).transpose()
    }

    fn required<T>(
        &self,
        key: &str,
        value: Result<Option<T>, ConfigError>,
    ) -> Result<T, ConfigError> {
        value?.ok_or_else(|| self.missing(key))
    }

    /// The raw value (multi-line values joined with `\n`).
    pub fn get_str(&self, key: &str) -> Result<&str, ConfigError> {
        self.entry(key)
            .map(Entry::value)
            .ok_or_else(|| self.missing(key))
    }

    pub fn get_str_opt(&self, key: &str) -> Option<&str> {
        self.entry(key).map(Entry::value)
    }

    pub fn get_f64(&self, key: &str, bounds: Bounds) -> Result<f64, ConfigError> {
        self.required(key, self.get_f64_opt(key, bounds))
    }

    /// The value, or `default` when absent (the default is not range-checked, as in Klipper).
    pub fn get_f64_or(&self, key: &str, default: f64, bounds: Bounds) -> Result<f64, ConfigError> {
        Ok(self.get_f64_opt(key, bounds)?.unwrap_or(default))
    }

    pub fn get_f64_opt(&self, key: &str, bounds: Bounds) -> Result<Option<f64>, ConfigError> {
        self.parse_opt(key, |entry| {
            let value = parse_f64(&entry.value).map_err(|m| self.invalid(entry, m))?;
            bounds.check(value).map_err(|m| self.invalid(entry, m))?;
            Ok(value)
        })
    }

    pub fn get_u32(&self, key: &str, bounds: Bounds) -> Result<u32, ConfigError> {
        self.required(key, self.get_u32_opt(key, bounds))
    }

    pub fn get_u32_or(&self, key: &str, default: u32, bounds: Bounds) -> Result<u32, ConfigError> {
        Ok(self.get_u32_opt(key, bounds)?.unwrap_or(default))
    }

    pub fn get_u32_opt(&self, key: &str, bounds: Bounds) -> Result<Option<u32>, ConfigError> {
        self.parse_opt(key, |entry| {
            let text = entry.value.trim();
            let value: u32 = text.parse().map_err(|_| {
                self.invalid(
                    entry,
                    format!("expected a whole number ≥ 0, found '{text}'"),
                )
            })?;
            bounds
                .check(f64::from(value))
                .map_err(|m| self.invalid(entry, m))?;
            Ok(value)
        })
    }

    pub fn get_bool(&self, key: &str) -> Result<bool, ConfigError> {
        self.required(key, self.get_bool_opt(key))
    }

    pub fn get_bool_or(&self, key: &str, default: bool) -> Result<bool, ConfigError> {
        Ok(self.get_bool_opt(key)?.unwrap_or(default))
    }

    pub fn get_bool_opt(&self, key: &str) -> Result<Option<bool>, ConfigError> {
        self.parse_opt(key, |entry| {
            parse_bool(&entry.value).map_err(|m| self.invalid(entry, m))
        })
    }

    /// A comma- (or newline-) separated list of numbers, e.g. `home_position: 0, 200, 0`.
    pub fn get_f64_list(&self, key: &str) -> Result<Vec<f64>, ConfigError> {
        self.required(key, self.get_f64_list_opt(key))
    }

    pub fn get_f64_list_opt(&self, key: &str) -> Result<Option<Vec<f64>>, ConfigError> {
        self.parse_opt(key, |entry| {
            let mut values = Vec::new();
            let mut line_start = 0;
            for line in entry.value.split('\n') {
                if !line.trim().is_empty() {
                    self.parse_list_line(entry, line, line_start, &mut values)?;
                }
                line_start += line.len() + 1;
            }
            Ok(values)
        })
    }

    /// Numbers of one value line, split at commas; an empty element is an error.
    fn parse_list_line(
        &self,
        entry: &Entry,
        line: &str,
        line_start: usize,
        values: &mut Vec<f64>,
    ) -> Result<(), ConfigError> {
        let mut offset = line_start;
        for part in line.split(',') {
            let lead = part.len() - part.trim_start().len();
            let item = part.trim();
            let span = entry.sub_span(offset + lead, item.len());
            let value = if item.is_empty() {
                Err("empty list element".to_string())
            } else {
                parse_f64(item)
            };
            values.push(value.map_err(|m| self.invalid_at(entry, span, m))?);
            offset += part.len() + 1;
        }
        Ok(())
    }

    /// A gear ratio list like `80:16, 3:1`, multiplied out in Klipper's order
    /// (`result = 1.0; for (g1, g2) { result *= g1 / g2 }`); absent → `default`, empty → 1.0.
    pub fn get_ratio_or(&self, key: &str, default: f64) -> Result<f64, ConfigError> {
        Ok(self.get_ratio_opt(key)?.unwrap_or(default))
    }

    pub fn get_ratio(&self, key: &str) -> Result<f64, ConfigError> {
        self.required(key, self.get_ratio_opt(key))
    }

    pub fn get_ratio_opt(&self, key: &str) -> Result<Option<f64>, ConfigError> {
        self.parse_opt(key, |entry| {
            let mut result = 1.0;
            for (offset, pair) in split_parts(&entry.value, &[',', '\n']) {
                let (g1, g2) = self.parse_ratio_pair(entry, offset, pair)?;
                result *= g1 / g2;
            }
            Ok(result)
        })
    }

    /// One `teeth:teeth` pair; both sides must be positive.
    fn parse_ratio_pair(
        &self,
        entry: &Entry,
        offset: usize,
        pair: &str,
    ) -> Result<(f64, f64), ConfigError> {
        let span = entry.sub_span(offset, pair.len());
        let sides: Vec<&str> = pair.split(':').collect();
        let [g1, g2] = sides.as_slice() else {
            return Err(self.invalid_at(
                entry,
                span,
                format!("'{pair}' must have 2 elements, like 80:16"),
            ));
        };
        let parse_side = |text: &str| -> Result<f64, ConfigError> {
            let value = parse_f64(text).map_err(|m| self.invalid_at(entry, span.clone(), m))?;
            if value <= 0.0 {
                return Err(self.invalid_at(
                    entry,
                    span.clone(),
                    format!("gear ratio '{pair}' must have positive terms"),
                ));
            }
            Ok(value)
        };
        Ok((parse_side(g1)?, parse_side(g2)?))
    }

    /// One of `choices` (compared case-insensitively).
    pub fn get_choice<T: Copy>(&self, key: &str, choices: &[(&str, T)]) -> Result<T, ConfigError> {
        self.required(key, self.get_choice_opt(key, choices))
    }

    pub fn get_choice_or<T: Copy>(
        &self,
        key: &str,
        choices: &[(&str, T)],
        default: T,
    ) -> Result<T, ConfigError> {
        Ok(self.get_choice_opt(key, choices)?.unwrap_or(default))
    }

    pub fn get_choice_opt<T: Copy>(
        &self,
        key: &str,
        choices: &[(&str, T)],
    ) -> Result<Option<T>, ConfigError> {
        self.parse_opt(key, |entry| {
            let text = entry.value.trim();
            choices
                .iter()
                .find(|(name, _)| name.eq_ignore_ascii_case(text))
                .map(|(_, value)| *value)
                .ok_or_else(|| {
                    let names: Vec<&str> = choices.iter().map(|(n, _)| *n).collect();
                    self.invalid(
                        entry,
                        format!(
                            "'{text}' is not a valid choice (expected one of: {})",
                            names.join(", ")
                        ),
                    )
                })
        })
    }

    /// A pin; `allow_pull` permits `^`/`~` (input pins such as endstops).
    pub fn get_pin(&self, key: &str, allow_pull: bool) -> Result<Pin, ConfigError> {
        self.required(key, self.get_pin_opt(key, allow_pull))
    }

    pub fn get_pin_opt(&self, key: &str, allow_pull: bool) -> Result<Option<Pin>, ConfigError> {
        self.parse_opt(key, |entry| {
            parse_pin(&entry.value, allow_pull).map_err(|m| self.invalid(entry, m))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pins_in_klipper_syntax() {
        let pin = parse_pin("~!PA2", true).ok();
        assert_eq!(
            pin,
            Some(Pin {
                chip: None,
                name: "PA2".into(),
                inverted: true,
                pull: Pull::Down
            })
        );
        let probe = parse_pin("probe:z_virtual_endstop", true).ok();
        assert_eq!(
            probe.as_ref().and_then(|p| p.chip.as_deref()),
            Some("probe")
        );
        assert_eq!(
            probe.map(|p| p.to_string()).as_deref(),
            Some("probe:z_virtual_endstop")
        );
        assert!(parse_pin("^PJ1", false).is_err());
        assert!(parse_pin("!^PJ1", true).is_err());
        assert!(parse_pin("PA 1", true).is_err());
        assert!(parse_pin("", true).is_err());
    }

    #[test]
    fn numbers_must_be_finite() {
        assert_eq!(parse_f64(" 2.5 "), Ok(2.5));
        assert_eq!(parse_f64("1e3"), Ok(1000.0));
        assert!(parse_f64("nan").is_err());
        assert!(parse_f64("inf").is_err());
        assert!(parse_f64("12,5").is_err());
    }

    #[test]
    fn booleans_like_configparser() {
        for t in ["True", "yes", "ON", "1"] {
            assert_eq!(parse_bool(t), Ok(true), "{t}");
        }
        for f in ["False", "no", "off", "0"] {
            assert_eq!(parse_bool(f), Ok(false), "{f}");
        }
        assert!(parse_bool("maybe").is_err());
    }

    #[test]
    fn bounds_follow_klipper() {
        let b = Bounds::NONE.above(0.0).max(10.0);
        assert!(b.check(0.0).is_err());
        assert!(b.check(10.0).is_ok());
        assert!(b.check(10.5).is_err());
        let r = Bounds::NONE.min(0.0).below(1.0);
        assert!(r.check(0.0).is_ok());
        assert!(r.check(1.0).is_err());
    }
}
