//! The generic reader: syntax, comments, multi-line values, includes, SAVE_CONFIG, merging, spans,
//! typed accessors and their error locations.

use std::fs;

use config::{Bounds, ConfigDocument, ConfigError, Pull};

fn doc(text: &str) -> ConfigDocument {
    match ConfigDocument::from_str(text, "printer.cfg") {
        Ok(doc) => doc,
        Err(err) => panic!("parse failed: {err}"),
    }
}

fn parse_err(text: &str) -> ConfigError {
    match ConfigDocument::from_str(text, "printer.cfg") {
        Ok(_) => panic!("expected a parse error for {text:?}"),
        Err(err) => err,
    }
}

fn value(doc: &ConfigDocument, section: &str, key: &str) -> Option<String> {
    doc.section(section)
        .and_then(|s| s.get_str_opt(key))
        .map(str::to_string)
}

#[test]
fn colon_and_equals_separate_the_same_way() {
    let d = doc("[s]\na: 1\nb = 2\nc:3\nd=4\ngear_ratio = 80:16\n");
    for (k, v) in [
        ("a", "1"),
        ("b", "2"),
        ("c", "3"),
        ("d", "4"),
        ("gear_ratio", "80:16"),
    ] {
        assert_eq!(value(&d, "s", k).as_deref(), Some(v), "{k}");
    }
}

#[test]
fn inline_comments_need_preceding_whitespace() {
    let d = doc("[s]\na: 1 # one\nb: 2 ; two\nc: x#y\nd: x;y\n# full line\n; full line\n");
    assert_eq!(value(&d, "s", "a").as_deref(), Some("1"));
    assert_eq!(value(&d, "s", "b").as_deref(), Some("2"));
    assert_eq!(value(&d, "s", "c").as_deref(), Some("x#y"));
    assert_eq!(value(&d, "s", "d").as_deref(), Some("x;y"));
    assert_eq!(d.section("s").map(|s| s.entries().len()), Some(4));
}

#[test]
fn multi_line_values_skip_comment_lines_and_keep_inner_blank_lines() {
    let text = "[gcode_macro START]\ngcode:\n  G28\n  # a comment inside\n\n  G1 Z5 ; lift\n\n\n[s]\nx: 1\n";
    let d = doc(text);
    assert_eq!(
        value(&d, "gcode_macro START", "gcode").as_deref(),
        Some("\nG28\n\nG1 Z5")
    );
    let section = d.section("gcode_macro START").expect("macro section");
    let entry = section.entry("gcode").expect("gcode entry");
    // The value's span is its first non-blank line.
    assert_eq!((entry.value_span().line, entry.value_span().column), (3, 3));
    assert_eq!(value(&d, "s", "x").as_deref(), Some("1"));
}

#[test]
fn polygon_style_lists_across_lines() {
    let d = doc("[bed]\npoints:\n   0, 0\n   10, 20\n");
    let list = d.section("bed").map(|s| s.get_f64_list("points"));
    assert_eq!(list.and_then(Result::ok), Some(vec![0.0, 0.0, 10.0, 20.0]));
}

#[test]
fn keys_are_case_insensitive_and_section_first_word_too() {
    let d = doc(
        "[STEPPER_X]\nMicroSteps: 16\n[gcode_macro Foo]\ngcode: A\n[gcode_macro foo]\ngcode: B\n",
    );
    assert_eq!(value(&d, "stepper_x", "microsteps").as_deref(), Some("16"));
    assert_eq!(d.section("stepper_x").map(|s| s.name()), Some("STEPPER_X"));
    assert_eq!(value(&d, "GCODE_MACRO Foo", "gcode").as_deref(), Some("A"));
    assert_eq!(value(&d, "gcode_macro foo", "gcode").as_deref(), Some("B"));
    assert_eq!(d.sections_of_kind("gcode_macro").count(), 2);
    assert_eq!(
        d.section("gcode_macro Foo").map(|s| s.argument()),
        Some("Foo")
    );
}

#[test]
fn duplicate_sections_merge_with_later_keys_winning() {
    let d = doc("[s]\na: 1\nb: 2\n[t]\n[s]\nb: 3\nc: 4\n");
    assert_eq!(d.sections().len(), 2);
    assert_eq!(value(&d, "s", "a").as_deref(), Some("1"));
    assert_eq!(value(&d, "s", "b").as_deref(), Some("3"));
    assert_eq!(value(&d, "s", "c").as_deref(), Some("4"));
    let span = d
        .section("s")
        .and_then(|s| s.entry("b"))
        .map(|e| e.value_span().line);
    assert_eq!(span, Some(6));
}

#[test]
fn save_config_block_overrides_earlier_values() {
    let text = "[printer]\nmax_accel: 3000\n\n\
#*# <---------------------- SAVE_CONFIG ---------------------->\n\
#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n\
#*#\n#*# [printer]\n#*# max_accel = 2500\n#*#\n#*# [probe]\n#*# z_offset = 1.2\n";
    let d = doc(text);
    assert_eq!(value(&d, "printer", "max_accel").as_deref(), Some("2500"));
    assert_eq!(value(&d, "probe", "z_offset").as_deref(), Some("1.2"));
    let span = d
        .section("printer")
        .and_then(|s| s.entry("max_accel"))
        .map(|e| e.value_span().clone());
    let span = span.expect("span");
    assert_eq!((span.line, span.column, span.len), (8, 17, 4));
    assert_eq!(span.text(), "2500");
    assert!(d.warnings().is_empty());
}

#[test]
fn damaged_save_config_block_is_ignored_with_a_warning() {
    let text = "[printer]\nmax_accel: 3000\n\
#*# <---------------------- SAVE_CONFIG ---------------------->\n\
#*# [printer]\n#*# max_accel = 2500\nmax_velocity: 5\n";
    let d = doc(text);
    assert_eq!(value(&d, "printer", "max_accel").as_deref(), Some("3000"));
    assert_eq!(d.warnings().len(), 1);
    assert_eq!(d.warnings()[0].span.as_ref().map(|s| s.line), Some(6));
}

#[test]
fn crlf_and_bom_read_like_lf() {
    let lf = "[s]\na: 1\ngcode:\n  G28\n  G1 X1\n";
    let crlf = format!("\u{feff}{}", lf.replace('\n', "\r\n"));
    let (a, b) = (doc(lf), doc(&crlf));
    assert_eq!(value(&a, "s", "gcode"), value(&b, "s", "gcode"));
    assert_eq!(value(&b, "s", "a").as_deref(), Some("1"));
    assert_eq!(value(&b, "s", "gcode").as_deref(), Some("\nG28\nG1 X1"));
}

#[test]
fn option_outside_a_section_is_an_error() {
    let err = parse_err("# header\nmax_velocity: 5\n");
    assert!(
        matches!(&err, ConfigError::Syntax { span, .. } if span.line == 2),
        "{err}"
    );
}

#[test]
fn lines_without_separator_and_bad_headers_are_errors() {
    assert!(
        matches!(parse_err("[s]\njust words\n"), ConfigError::Syntax { span, .. } if span.line == 2)
    );
    assert!(matches!(parse_err("[s\n"), ConfigError::Syntax { .. }));
    assert!(matches!(parse_err("[]\n"), ConfigError::Syntax { .. }));
    let err = parse_err("[s] trailing\n");
    assert!(
        matches!(&err, ConfigError::Syntax { span, .. } if span.column == 5),
        "{err}"
    );
    assert!(matches!(
        parse_err("[s]\n: 5\n"),
        ConfigError::Syntax { .. }
    ));
}

#[test]
fn bad_number_points_at_line_and_column() {
    let d = doc("[printer]\nkinematics: polar\nmax_velocity:   3o0 # typo\n");
    let printer = d.section("printer").expect("printer");
    let err = printer
        .get_f64("max_velocity", Bounds::NONE)
        .expect_err("not a number");
    let ConfigError::InvalidValue {
        span, section, key, ..
    } = &err
    else {
        panic!("wrong error {err}");
    };
    assert_eq!((span.line, span.column, span.len), (3, 17, 3));
    assert_eq!(
        (section.as_str(), key.as_str()),
        ("printer", "max_velocity")
    );
    assert_eq!(
        err.to_string().split(':').take(3).collect::<Vec<_>>(),
        ["printer.cfg", "3", "17"]
    );
    assert_eq!(
        span.underlined(),
        "max_velocity:   3o0 # typo\n                ^^^"
    );
}

#[test]
fn missing_required_key_points_at_section_header() {
    let d = doc("# c\n\n  [printer]\nkinematics: polar\n");
    let printer = d.section("printer").expect("printer");
    let err = printer
        .get_f64("max_accel", Bounds::NONE)
        .expect_err("missing");
    let ConfigError::MissingKey { span, section, key } = &err else {
        panic!("wrong error {err}");
    };
    assert_eq!((span.line, span.column), (3, 3));
    assert_eq!((section.as_str(), key.as_str()), ("printer", "max_accel"));
}

#[test]
fn bounds_are_checked_like_klipper() {
    let d = doc("[s]\nzero: 0\nneg: -1\nbig: 11\nnan: nan\n");
    let s = d.section("s").expect("s");
    assert!(s.get_f64("zero", Bounds::NONE.above(0.0)).is_err());
    assert!(s.get_f64("zero", Bounds::NONE.min(0.0)).is_ok());
    assert!(s.get_f64("neg", Bounds::NONE.min(0.0)).is_err());
    assert!(s.get_f64("big", Bounds::NONE.max(10.0)).is_err());
    assert!(s.get_f64("big", Bounds::NONE.below(11.0)).is_err());
    assert!(s.get_f64("nan", Bounds::NONE).is_err());
    assert_eq!(
        s.get_f64_or("absent", 7.0, Bounds::NONE.above(100.0)).ok(),
        Some(7.0)
    );
    assert!(s.get_u32("neg", Bounds::NONE).is_err());
}

#[test]
fn gear_ratios_multiply_in_klippers_order() {
    let d = doc("[s]\na: 80:16, 3:1\nb: 57:11\nc:\nbad: 80:0\nodd: 80:16:2\n");
    let s = d.section("s").expect("s");
    assert_eq!(
        s.get_ratio("a").ok(),
        Some(1.0 * (80.0 / 16.0) * (3.0 / 1.0))
    );
    assert_eq!(s.get_ratio("b").ok(), Some(57.0 / 11.0));
    assert_eq!(s.get_ratio("c").ok(), Some(1.0));
    assert_eq!(s.get_ratio_or("absent", 1.0).ok(), Some(1.0));
    let err = s.get_ratio("bad").expect_err("80:0");
    assert!(
        matches!(&err, ConfigError::InvalidValue { span, .. } if (span.line, span.column, span.len) == (5, 6, 4)),
        "{err}"
    );
    assert!(s.get_ratio("odd").is_err());
}

#[test]
fn list_errors_point_at_the_element() {
    let d = doc("[printer]\nhome_position: 0, 2x0, 0\n");
    let err = d
        .section("printer")
        .expect("printer")
        .get_f64_list("home_position")
        .expect_err("bad");
    assert!(
        matches!(&err, ConfigError::InvalidValue { span, .. } if (span.column, span.len) == (19, 3)),
        "{err}"
    );
}

#[test]
fn booleans_choices_and_pins() {
    let d = doc(
        "[s]\nt: True\nf: no\nbad: perhaps\nc: Right\nend: ~!PA2\nstep: ^PA3\nz: probe:z_virtual_endstop\n",
    );
    let s = d.section("s").expect("s");
    assert_eq!(s.get_bool("t").ok(), Some(true));
    assert_eq!(s.get_bool("f").ok(), Some(false));
    assert!(s.get_bool("bad").is_err());
    assert_eq!(
        s.get_choice("c", &[("left", 1), ("right", 2)]).ok(),
        Some(2)
    );
    assert!(s.get_choice("t", &[("left", 1), ("right", 2)]).is_err());
    let pin = s.get_pin("end", true).expect("pin");
    assert!(pin.inverted && pin.pull == Pull::Down && pin.name == "PA2");
    assert!(s.get_pin("step", false).is_err());
    assert_eq!(
        s.get_pin("z", true).ok().and_then(|p| p.chip),
        Some("probe".to_string())
    );
}

#[test]
fn unread_keys_are_reported() {
    let d = doc("[printer]\nmax_velocity: 3\nmax_velocty: 4\n");
    let printer = d.section("printer").expect("printer");
    let _ = printer.get_f64("max_velocity", Bounds::NONE);
    let unused: Vec<&str> = printer.unused_entries().map(|e| e.key()).collect();
    assert_eq!(unused, ["max_velocty"]);
    assert!(printer.contains("max_velocty"));
    assert_eq!(
        printer.unused_entries().count(),
        1,
        "contains() does not count as reading"
    );
}

#[test]
fn non_utf8_file_is_an_error_with_position() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("printer.cfg");
    fs::write(&path, b"[printer]\nname: ab\xff\n").expect("write");
    let err = ConfigDocument::load(&path).expect_err("not utf-8");
    assert!(
        matches!(
            err,
            ConfigError::NotUtf8 {
                line: 2,
                column: 9,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn missing_file_is_an_io_error() {
    let err = ConfigDocument::load("/nonexistent/dir/printer.cfg").expect_err("missing");
    assert!(matches!(err, ConfigError::Io { .. }));
}

#[test]
fn include_with_relative_paths_nests_from_each_files_folder() {
    let dir = tempfile::tempdir().expect("tempdir");
    fs::create_dir_all(dir.path().join("parts/deeper")).expect("mkdir");
    fs::write(
        dir.path().join("printer.cfg"),
        "[include parts/motion.cfg]\n[s]\na: main\n",
    )
    .expect("write");
    fs::write(
        dir.path().join("parts/motion.cfg"),
        "[s]\na: part\nb: part\n[include deeper/x.cfg]\n",
    )
    .expect("write");
    fs::write(dir.path().join("parts/deeper/x.cfg"), "[t]\nc: deep\n").expect("write");
    let d = ConfigDocument::load(dir.path().join("printer.cfg")).expect("loads");
    assert_eq!(
        value(&d, "s", "a").as_deref(),
        Some("main"),
        "the including file's later value wins"
    );
    assert_eq!(value(&d, "s", "b").as_deref(), Some("part"));
    assert_eq!(value(&d, "t", "c").as_deref(), Some("deep"));
    assert_eq!(d.files().len(), 3);
    let span = d
        .section("t")
        .and_then(|s| s.entry("c"))
        .map(|e| e.value_span().clone())
        .expect("span");
    assert!(span.file.ends_with("parts/deeper/x.cfg"));
}

#[test]
fn include_glob_reads_matches_in_sorted_order() {
    let dir = tempfile::tempdir().expect("tempdir");
    fs::create_dir_all(dir.path().join("macros")).expect("mkdir");
    fs::write(
        dir.path().join("macros/b.cfg"),
        "[s]\nv: b\n[gcode_macro B]\ngcode: B\n",
    )
    .expect("write");
    fs::write(dir.path().join("macros/a.cfg"), "[s]\nv: a\nw: a\n").expect("write");
    fs::write(dir.path().join("macros/.hidden.cfg"), "[s]\nv: hidden\n").expect("write");
    fs::write(
        dir.path().join("printer.cfg"),
        "[include macros/*.cfg]\n[include none/*.cfg]\n",
    )
    .expect("write");
    let d = ConfigDocument::load(dir.path().join("printer.cfg")).expect("loads");
    assert_eq!(value(&d, "s", "v").as_deref(), Some("b"));
    assert_eq!(value(&d, "s", "w").as_deref(), Some("a"));
    assert!(d.section("gcode_macro B").is_some());
}

#[test]
fn missing_include_without_wildcards_is_an_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    fs::write(
        dir.path().join("printer.cfg"),
        "[s]\n\n[include nothere.cfg]\n",
    )
    .expect("write");
    let err = ConfigDocument::load(dir.path().join("printer.cfg")).expect_err("missing include");
    assert!(
        matches!(&err, ConfigError::IncludeNotFound { span, .. } if span.line == 3),
        "{err}"
    );
}

#[test]
fn include_cycle_is_an_error_naming_the_chain() {
    let dir = tempfile::tempdir().expect("tempdir");
    fs::write(dir.path().join("printer.cfg"), "[include a.cfg]\n").expect("write");
    fs::write(dir.path().join("a.cfg"), "[include b.cfg]\n").expect("write");
    fs::write(
        dir.path().join("b.cfg"),
        "[s]\nx: 1\n[include printer.cfg]\n",
    )
    .expect("write");
    let err = ConfigDocument::load(dir.path().join("printer.cfg")).expect_err("cycle");
    let ConfigError::IncludeCycle { span, chain } = &err else {
        panic!("wrong error {err}");
    };
    assert!(span.file.ends_with("b.cfg") && span.line == 3);
    let names: Vec<String> = chain
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    assert_eq!(names, ["printer.cfg", "a.cfg", "b.cfg", "printer.cfg"]);
    assert!(err.to_string().contains("a.cfg -> "));
}

#[test]
fn same_file_included_twice_is_not_a_cycle() {
    let dir = tempfile::tempdir().expect("tempdir");
    fs::write(
        dir.path().join("printer.cfg"),
        "[include a.cfg]\n[include a.cfg]\n",
    )
    .expect("write");
    fs::write(dir.path().join("a.cfg"), "[s]\nx: 1\n").expect("write");
    assert!(ConfigDocument::load(dir.path().join("printer.cfg")).is_ok());
}

#[test]
fn options_after_an_include_need_a_section_header() {
    let dir = tempfile::tempdir().expect("tempdir");
    fs::write(dir.path().join("a.cfg"), "[t]\ny: 2\n").expect("write");
    fs::write(
        dir.path().join("printer.cfg"),
        "[s]\n[include a.cfg]\nx: 1\n",
    )
    .expect("write");
    let err = ConfigDocument::load(dir.path().join("printer.cfg")).expect_err("no section");
    assert!(
        matches!(&err, ConfigError::Syntax { span, .. } if span.line == 3),
        "{err}"
    );
}
