//! `run --host kalico-fekt --klipper-batch` plans as the FEKT-SCARA fork did for the shared `scara-fekt-*` golden
//! cases: every planned move (the moves CSV the command writes, read back) equal to the fork's trapq rows.

use std::process::Command;

use stepgen::read_moves_csv;

use crate::common::{binary, shared};

#[test]
fn kalico_fekt_host_plans_as_the_fork() {
    let Some(shared) = shared("kalico_fekt_host_plans_as_the_fork") else {
        return;
    };
    for case in ["scara-fekt-synthetic", "scara-fekt-cura-hex"] {
        let dir = shared.join("golden").join(case);
        let out = tempfile::tempdir().expect("temp dir");
        let moves = out.path().join("moves.csv");
        let output = Command::new(binary())
            .arg("run")
            .arg("-c")
            .arg(dir.join("printer.cfg"))
            .args(["--klipper-batch", "--host", "kalico-fekt", "--moves"])
            .arg(&moves)
            .arg(dir.join("input.gcode"))
            .output()
            .expect("jointspace runs");
        assert!(
            output.status.success(),
            "{case}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        let ours = read_moves_csv(&moves).expect("our moves CSV");
        let theirs = read_moves_csv(dir.join("moves.csv.gz")).expect("golden moves");
        assert_eq!(ours.len(), theirs.len(), "{case}: move count");
        assert!(
            (ours[0].1.print_time - 0.251).abs() < 1e-12,
            "{case}: first move at {}",
            ours[0].1.print_time
        );
        if let Some(i) = (0..ours.len()).find(|&i| ours[i] != theirs[i]) {
            panic!(
                "{case}: move {i} differs: ours {:?}, the fork's {:?}",
                ours[i], theirs[i]
            );
        }
    }
}
