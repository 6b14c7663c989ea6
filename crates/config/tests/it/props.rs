//! Property tests: no input text makes the reader panic, and values survive any key/separator spelling.

use config::{ConfigDocument, MachineConfig};
use proptest::prelude::*;

/// Lines built from config-like fragments, so generated files reach deep into the reader.
fn config_line() -> impl Strategy<Value = String> {
    let fragments = prop_oneof![
        Just("[printer]".to_string()),
        Just("[stepper_bed]".to_string()),
        Just("[stepper_arm]".to_string()),
        Just("[stepper_z]".to_string()),
        Just("[extruder]".to_string()),
        Just("kinematics: polar".to_string()),
        Just("kinematics: scara".to_string()),
        Just("#*# <---------------------- SAVE_CONFIG ---------------------->".to_string()),
        Just("#*# [printer]".to_string()),
        Just("gear_ratio: 80:16, 3:1".to_string()),
        "[a-z_]{1,12}[:=] ?[-0-9.e:,!^~ a-zA-Z]{0,12}",
        "[ \t]{0,3}[#;]?[ -~]{0,20}",
        "\\[[ -~]{0,10}\\]?",
        any::<String>(),
    ];
    (
        prop_oneof![Just(""), Just("  "), Just("\t"), Just("#*# ")],
        fragments,
    )
        .prop_map(|(indent, text)| format!("{indent}{text}"))
        .prop_filter("no includes (they would read the file system)", |l| {
            !l.contains("include")
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]

    #[test]
    fn arbitrary_text_never_panics(text in any::<String>()) {
        let text = text.replace("include", "inc");
        let _ = ConfigDocument::from_str(&text, "printer.cfg");
        let _ = MachineConfig::from_str(&text, "printer.cfg");
    }

    #[test]
    fn config_like_text_never_panics(lines in prop::collection::vec(config_line(), 0..40), crlf in any::<bool>()) {
        let text = lines.join(if crlf { "\r\n" } else { "\n" });
        if let Ok(doc) = ConfigDocument::from_str(&text, "printer.cfg") {
            for section in doc.sections() {
                for entry in section.entries() {
                    let span = entry.value_span();
                    // Spans always lie within their line.
                    prop_assert!(span.column >= 1);
                    prop_assert!(span.column - 1 + span.len <= span.line_text.chars().count());
                    let _ = span.underlined();
                }
            }
        }
        let _ = MachineConfig::from_str(&text, "printer.cfg");
    }

    #[test]
    fn values_read_back_whatever_the_spelling(
        key in "[a-z][a-z_]{0,10}",
        upper in any::<bool>(),
        equals in any::<bool>(),
        pad in "[ \t]{0,3}",
        number in -1e9f64..1e9,
    ) {
        let written_key = if upper { key.to_uppercase() } else { key.clone() };
        let sep = if equals { "=" } else { ":" };
        let text = format!("[s]\n{written_key}{pad}{sep}{pad}{number:?}{pad} # note\n");
        let doc = ConfigDocument::from_str(&text, "p.cfg").map_err(|e| TestCaseError::fail(e.to_string()))?;
        let section = doc.section("s").ok_or_else(|| TestCaseError::fail("no section"))?;
        let read = section.get_f64(&key, config::Bounds::NONE).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(read.to_bits(), number.to_bits());
    }
}
