#[test]
fn quick_numbers() {
    let t = std::time::Instant::now();
    let l = sim::scenario::polar_lateral_offset_loop(None).unwrap();
    println!("{:?} before {:?}\nafter {:?}\n{:?}", t.elapsed(), l.before.replay.deposited.summary(), l.after.replay.deposited.summary(), l.correction);
    for c in &l.before.circles { println!("B {c:?}"); }
    for c in &l.after.circles { println!("A {c:?}"); }
    let l = sim::scenario::scara_coupling_loop().unwrap();
    println!("{:?} before {:?}\nafter {:?}\n{:?}", t.elapsed(), l.before.replay.deposited.summary(), l.after.replay.deposited.summary(), l.correction);
    for c in &l.before.circles { println!("B {c:?}"); }
    for c in &l.after.circles { println!("A {c:?}"); }
}
