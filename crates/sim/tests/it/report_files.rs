//! The report folder: every file is written, the JSON parses and carries the numbers of the text.

use sim::scenario::polar_lateral_offset_demo;

#[test]
fn report_folder_has_text_json_and_pictures() {
    let dir = tempfile::tempdir().expect("tempdir");
    let report = polar_lateral_offset_demo(dir.path()).expect("demo");
    for name in sim::report::REPORT_FILES {
        let meta = std::fs::metadata(dir.path().join(name)).expect(name);
        assert!(meta.len() > 1000, "{name} is only {} bytes", meta.len());
    }
    let png = std::fs::read(dir.path().join("overlay.png")).expect("png");
    assert_eq!(&png[1..4], b"PNG");
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("report.json")).expect("json"),
    )
    .expect("parse");
    let max = json["before"]["deposited"]["max_path_deviation"]
        .as_f64()
        .expect("number");
    assert_eq!(max, report.before.deposited.max_path_deviation);
    assert!(
        json["after"]["circles"]
            .as_array()
            .is_some_and(|c| !c.is_empty())
    );
    assert!(json["correction"]["values"][1]["name"] == "arm_lateral_offset");
    let text = std::fs::read_to_string(dir.path().join("report.txt")).expect("text");
    assert!(text.contains("after correction") && text.contains(&format!("{max:.4}")));
    // No temporary files left behind.
    let leftovers = std::fs::read_dir(dir.path())
        .expect("dir")
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .count();
    assert_eq!(leftovers, 0);
}
