//! The library's `struct stepper_kinematics` is each host's: a C program built against the host's own
//! `itersolve.h` reports the size and offsets, and the library must report the same.

use std::process::Command;

use jointspace_klipper::jointspace_stepper_kinematics_layout;

use crate::hosts::{Hosts, KALICO, KALICO_FEKT, KLIPPER};

const PROBE: &str = r#"
#include <stdio.h>
#include <stddef.h>
#include "itersolve.h"
int main(void) {
    printf("%zu %zu %zu %zu %zu\n", sizeof(struct stepper_kinematics),
           offsetof(struct stepper_kinematics, commanded_pos),
           offsetof(struct stepper_kinematics, active_flags),
           offsetof(struct stepper_kinematics, calc_position_cb),
           offsetof(struct stepper_kinematics, post_cb));
    return 0;
}
"#;

#[test]
fn stepper_kinematics_layout_is_each_hosts() {
    let Some(hosts) = Hosts::get("stepper_kinematics_layout_is_each_hosts") else {
        return;
    };
    let mut ours = [0usize; 5];
    // SAFETY: five slots.
    unsafe { jointspace_stepper_kinematics_layout(ours.as_mut_ptr()) };
    let dir = tempfile::tempdir().expect("temp dir");
    let source = dir.path().join("probe.c");
    std::fs::write(&source, PROBE).expect("write probe");
    for host in [KLIPPER, KALICO, KALICO_FEKT] {
        let binary = dir.path().join(host);
        let include = hosts.tree(host, false).join("klippy/chelper");
        let built = Command::new("cc")
            .arg("-I")
            .arg(&include)
            .arg(&source)
            .arg("-o")
            .arg(&binary)
            .status()
            .expect("cc runs");
        assert!(built.success(), "{host}: probe did not compile");
        let output = Command::new(&binary).output().expect("probe runs");
        let theirs: Vec<usize> = String::from_utf8_lossy(&output.stdout)
            .split_whitespace()
            .map(|w| w.parse().expect("number"))
            .collect();
        assert_eq!(
            theirs,
            ours.to_vec(),
            "{host}: size, commanded_pos, active_flags, calc_position_cb, post_cb"
        );
    }
}
