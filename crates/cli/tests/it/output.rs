//! Output streams: a reader that goes away (`jointspace … | head -1`) must not make the binary panic.

use std::process::{Command, Stdio};

use crate::common::{CircleStream, binary, example_machine};

#[test]
fn closed_stdout_is_not_a_panic() {
    let scratch = tempfile::tempdir().expect("temp dir");
    let input = scratch.path().join("print.gcode");
    std::fs::write(&input, CircleStream::new().to_vec(1 << 16)).expect("write input");
    for args in [vec!["stats"], vec!["run", "-c"]] {
        let mut command = Command::new(binary());
        command.args(&args);
        if args[0] == "run" {
            command.arg(example_machine("cartesian"));
        }
        let mut child = command
            .arg(&input)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start jointspace");
        // Close the read end before the summary is printed.
        drop(child.stdout.take());
        let output = child.wait_with_output().expect("wait for jointspace");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            !stderr.contains("panicked") && output.status.code() != Some(101),
            "`{}` panicked when its stdout closed ({}):\n{stderr}",
            args[0],
            output.status
        );
    }
}
