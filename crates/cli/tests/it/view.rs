//! `view`: the page opened in headless Chromium. No console message and no script error; the numbers the page
//! shows are `estimate --json`'s; the pixels where the page draws a line the estimate lists as slowed have the
//! colour of the limit that slowed it (and without that limit in the config, another colour); a refused move is
//! drawn and listed at its line; the 3D view draws the path; bad input is refused as `estimate` refuses it, with
//! no page written. Chromium is Debian's `chromium` (`.ci/run` installs it); without it these tests fail when
//! `JOINTSPACE_REQUIRE_SHARED` is set (CI) and say they were skipped otherwise.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{binary, example_machine, shared};

/// Debian's Chromium, or `None` (skipped) where it is missing and CI does not require it.
fn chromium(test: &str) -> Option<PathBuf> {
    let found = std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|dir| dir.join("chromium"))
            .find(|p| p.is_file())
    });
    if found.is_none() {
        assert!(
            std::env::var_os("JOINTSPACE_REQUIRE_SHARED").is_none(),
            "chromium is not installed, and JOINTSPACE_REQUIRE_SHARED says the browser tests must run (CI: .ci/run \
             installs it)"
        );
        println!("{test}: skipped: chromium is not installed (apt-get install chromium)");
    }
    found
}

/// Headless Chromium on a page: `--dump-dom` or `--screenshot=FILE`; its DOM (or nothing) and its log.
fn browse(chromium: &Path, page: &Path, fragment: &str, action: &str) -> (String, String) {
    let profile = tempfile::tempdir().expect("profile dir");
    let url = format!("file://{}#{fragment}", page.display());
    let output = Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--enable-unsafe-swiftshader",
            "--use-angle=swiftshader",
            "--force-device-scale-factor=1",
            "--hide-scrollbars",
            "--window-size=1300,1000",
            "--enable-logging=stderr",
            "--v=0",
        ])
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg(action)
        .arg(&url)
        .output()
        .expect("chromium runs");
    assert!(
        output.status.success(),
        "chromium on {url}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let log = String::from_utf8_lossy(&output.stderr).into_owned();
    (String::from_utf8_lossy(&output.stdout).into_owned(), log)
}

/// The page loaded, its script finished, and nothing was written to the console or caught as an error.
fn assert_clean(dom: &str, log: &str) {
    assert!(
        dom.contains("data-ready=\"yes\""),
        "the page did not finish: {dom:.2000}"
    );
    // Chromium's software WebGL (SwiftShader) reports its own performance notes through the page's console
    // ("GL Driver Message … GPU stall due to ReadPixels" when the compositor reads the canvas back): the
    // browser's, not the page's.
    let console: Vec<&str> = log
        .lines()
        .filter(|l| l.contains(":CONSOLE") && !l.contains("GL Driver Message (OpenGL, Performance"))
        .collect();
    assert!(console.is_empty(), "console messages: {console:#?}");
    assert!(
        dom.contains("<ul id=\"errors\" hidden=\"\"></ul>"),
        "script errors on the page"
    );
}

/// An attribute of the element with `id` in a dumped DOM.
fn attribute(dom: &str, id: &str, name: &str) -> Option<String> {
    let start = dom.find(&format!("id=\"{id}\""))?;
    let tag_start = dom[..start].rfind('<')?;
    let tag = &dom[tag_start..tag_start + dom[tag_start..].find('>')?];
    let key = format!("{name}=\"");
    let at = tag.find(&key)? + key.len();
    Some(tag[at..at + tag[at..].find('"')?].to_string())
}

fn number(dom: &str, id: &str) -> f64 {
    let text = attribute(dom, id, "data-value").unwrap_or_else(|| panic!("no #{id} with a value"));
    text.parse()
        .unwrap_or_else(|_| panic!("#{id}: {text} is not a number"))
}

fn jointspace(args: &[&str]) -> std::process::Output {
    Command::new(binary())
        .args(args)
        .stdin(std::process::Stdio::null())
        .output()
        .expect("jointspace runs")
}

/// `view` of `gcode` on `config` into `page`; its standard error.
fn view(config: &Path, gcode: &Path, page: &Path) -> String {
    let out = jointspace(&[
        "view",
        "-c",
        &config.display().to_string(),
        &gcode.display().to_string(),
        "-o",
        &page.display().to_string(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "view failed: {stderr}");
    stderr
}

/// The polar golden machine's synthetic case, with its bed limited to 5 rad/s and 200 rad/s² (or as it is).
fn polar_case(shared: &Path, dir: &Path, limited: bool) -> (PathBuf, PathBuf) {
    let case = shared.join("golden/polar-synthetic");
    let text = std::fs::read_to_string(case.join("printer.cfg")).expect("config");
    let text = if limited {
        text.replacen(
            "kinematics: polar",
            "kinematics: polar\nmax_angular_velocity: 5\nmax_angular_accel: 200",
            1,
        )
    } else {
        text
    };
    let config = dir.join(if limited { "limited.cfg" } else { "free.cfg" });
    std::fs::write(&config, text).expect("write config");
    (config, case.join("input.gcode"))
}

#[test]
fn view_page_shows_the_estimates_numbers_without_console_errors() {
    let (Some(shared), Some(chromium)) = (
        shared("view_page_shows_the_estimates_numbers"),
        chromium("view_page_shows_the_estimates_numbers"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let (config, gcode) = polar_case(&shared, dir.path(), true);
    let page = dir.path().join("page.html");
    view(&config, &gcode, &page);
    let out = jointspace(&[
        "estimate",
        "--json",
        "-c",
        &config.display().to_string(),
        &gcode.display().to_string(),
    ]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("estimate JSON");
    let (dom, log) = browse(&chromium, &page, "", "--dump-dom");
    assert_clean(&dom, &log);
    let expect = |key: &str| json[key].as_f64().unwrap_or_else(|| panic!("{key}"));
    assert_eq!(number(&dom, "total"), expect("total"));
    assert_eq!(
        number(&dom, "without-limits"),
        expect("without_motor_limits")
    );
    assert_eq!(number(&dom, "slowed-total"), expect("slowed_total"));
    assert_eq!(
        number(&dom, "layer-count"),
        json["layers"].as_array().expect("layers").len() as f64
    );
    assert_eq!(
        attribute(&dom, "slicer", "data-value").as_deref(),
        Some("null")
    );
    let limit = &json["limits"][0];
    assert_eq!(limit["motor"], "stepper_bed");
    assert_eq!(
        number(&dom, "limit-stepper_bed"),
        limit["lost"].as_f64().expect("lost")
    );
    // The bed's peak speed and acceleration, read along every planned move, within the limits the planner keeps,
    // and the speed limit reached (the synthetic case passes the centre).
    let speed = number(&dom, "peak-stepper_bed-speed");
    let accel = number(&dom, "peak-stepper_bed-accel");
    assert!(
        (4.5..=5.0 * 1.01).contains(&speed),
        "bed peak {speed} rad/s against 5"
    );
    assert!(accel <= 200.0 * 1.05, "bed peak {accel} rad/s² against 200");
}

/// The legend's colour of each cause: (cause, label, rgb).
fn legend(dom: &str) -> Vec<(u8, String, [u8; 3])> {
    let mut out = Vec::new();
    let list = &dom[dom.find("id=\"legend\"").expect("legend")..];
    let list = &list[..list.find("</ul>").expect("legend's end")];
    for item in list.split("<li ").skip(1) {
        let value = |name: &str| {
            let key = format!("{name}=\"");
            let at = item.find(&key)? + key.len();
            Some(item[at..at + item[at..].find('"')?].to_string())
        };
        let (Some(cause), Some(rgb)) = (value("data-cause"), value("data-rgb")) else {
            continue;
        };
        let rgb: Vec<u8> = rgb
            .split(',')
            .map(|c| c.parse().expect("channel"))
            .collect();
        let label = item[item.find("</span>").expect("swatch") + 7..]
            .trim_end_matches("</li>")
            .to_string();
        out.push((
            cause.parse().expect("cause"),
            label,
            [rgb[0], rgb[1], rgb[2]],
        ));
    }
    out
}

/// The colour of the screenshot at the page's focus point (the focused segment's middle).
fn focus_pixel(chromium: &Path, page: &Path, fragment: &str, dir: &Path) -> ([u8; 3], String) {
    let (dom, log) = browse(chromium, page, fragment, "--dump-dom");
    assert_clean(&dom, &log);
    let x: f64 = attribute(&dom, "focus", "data-x")
        .expect("focus x")
        .parse()
        .expect("x");
    let y: f64 = attribute(&dom, "focus", "data-y")
        .expect("focus y")
        .parse()
        .expect("y");
    let shot = dir.join("shot.png");
    browse(
        chromium,
        page,
        fragment,
        &format!("--screenshot={}", shot.display()),
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&shot).expect("png"),
    ));
    let mut reader = decoder.read_info().expect("png header");
    let mut pixels = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut pixels).expect("png frame");
    let channels = info.color_type.samples();
    let at = (y.round() as usize * info.width as usize + x.round() as usize) * channels;
    ([pixels[at], pixels[at + 1], pixels[at + 2]], dom)
}

fn close(a: [u8; 3], b: [u8; 3]) -> bool {
    a.iter().zip(b).all(|(a, b)| a.abs_diff(b) <= 4)
}

#[test]
fn view_draws_a_slowed_line_in_the_colour_of_the_limit_that_slowed_it() {
    let (Some(shared), Some(chromium)) = (
        shared("view_draws_a_slowed_line_in_its_limits_colour"),
        chromium("view_draws_a_slowed_line_in_its_limits_colour"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let (config, gcode) = polar_case(&shared, dir.path(), true);
    let out = jointspace(&[
        "estimate",
        "--json",
        "-c",
        &config.display().to_string(),
        &gcode.display().to_string(),
    ]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("estimate JSON");
    // The estimate's slowed lines that move in XY only (a Z move is slowed by the Z limits too).
    let text = std::fs::read_to_string(&gcode).expect("gcode");
    let lines: Vec<u64> = json["slowed"]
        .as_array()
        .expect("slowed")
        .iter()
        .map(|s| s["line"].as_u64().expect("line"))
        .filter(|l| {
            !text
                .lines()
                .nth(*l as usize - 1)
                .unwrap_or("")
                .contains('Z')
        })
        .take(3)
        .collect();
    assert!(!lines.is_empty(), "the case has slowed lines");
    let page = dir.path().join("limited.html");
    view(&config, &gcode, &page);
    for line in &lines {
        let (pixel, dom) = focus_pixel(
            &chromium,
            &page,
            &format!("colour=cause&line={line}"),
            dir.path(),
        );
        let bed: Vec<_> = legend(&dom)
            .into_iter()
            .filter(|(_, label, _)| label.starts_with("stepper_bed"))
            .collect();
        assert!(
            bed.iter().any(|(_, _, rgb)| close(pixel, *rgb)),
            "line {line}: pixel {pixel:?}, the bed limits' colours {bed:?}"
        );
    }
    // Without the bed's limits nothing slows these lines: they are drawn in another colour.
    let (config, _) = polar_case(&shared, dir.path(), false);
    let page = dir.path().join("free.html");
    view(&config, &gcode, &page);
    for line in &lines {
        let (pixel, dom) = focus_pixel(
            &chromium,
            &page,
            &format!("colour=cause&line={line}"),
            dir.path(),
        );
        let entries = legend(&dom);
        assert!(
            entries
                .iter()
                .all(|(_, label, _)| !label.starts_with("stepper_bed"))
        );
        let (_, label, _) = entries
            .iter()
            .find(|(_, _, rgb)| close(pixel, *rgb))
            .unwrap_or_else(|| panic!("line {line}: pixel {pixel:?} is none of {entries:?}"));
        assert!(
            label == "at the requested speed" || label == "acceleration and corners",
            "{label}"
        );
    }
}

/// A print on the example polar machine (arm travel 150 mm) whose line 5 goes beyond the arm's reach.
const REFUSED_PRINT: &str =
    "G28\nG90\nM83\nG1 Z0.3 X10 Y0 F1200\nG1 X200 Y0 E2\nG1 X20 Y10 E1\nG1 X20 Y30 E1\n";

#[test]
fn view_shows_a_refused_move_at_its_line() {
    let Some(chromium) = chromium("view_shows_a_refused_move_at_its_line") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let gcode = dir.path().join("part.gcode");
    std::fs::write(&gcode, REFUSED_PRINT).expect("write");
    let page = dir.path().join("part.html");
    let stderr = view(&example_machine("polar"), &gcode, &page);
    assert!(
        stderr.contains("part.gcode:5:"),
        "the refusal at its line: {stderr}"
    );
    let (pixel, dom) = focus_pixel(&chromium, &page, "line=5", dir.path());
    assert_eq!(number(&dom, "refused-total"), 1.0);
    assert!(
        dom.contains("line 5: "),
        "the refused move listed at its line"
    );
    let refused = legend(&dom)
        .into_iter()
        .find(|(_, label, _)| label == "refused by the machine");
    let (_, _, rgb) = refused.expect("the refusal's colour in the legend");
    assert!(
        close(pixel, rgb),
        "pixel {pixel:?} against the refusal's {rgb:?}"
    );
}

#[test]
fn view_draws_the_path_in_3d() {
    let Some(chromium) = chromium("view_draws_the_path_in_3d") else {
        return;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let gcode = dir.path().join("part.gcode");
    // Ten layers of a 40 mm square.
    let mut text = String::from("G28\nG90\nM83\nG1 X-20 Y-20 Z0.3 F6000\n");
    for layer in 0..10 {
        text += &format!(";LAYER:{layer}\nG1 Z{:.1}\n", 0.3 + 0.3 * f64::from(layer));
        for (x, y) in [(20, -20), (20, 20), (-20, 20), (-20, -20)] {
            text += &format!("G1 X{x} Y{y} E2 F1800\n");
        }
    }
    std::fs::write(&gcode, text).expect("write");
    let page = dir.path().join("part.html");
    view(&example_machine("polar"), &gcode, &page);
    let shot = dir.path().join("3d.png");
    let (dom, log) = browse(&chromium, &page, "view=3d&colour=cause", "--dump-dom");
    assert_clean(&dom, &log);
    assert!(
        dom.contains("<div id=\"gl-note\" hidden=\"\">"),
        "WebGL unavailable"
    );
    browse(
        &chromium,
        &page,
        "view=3d&colour=cause",
        &format!("--screenshot={}", shot.display()),
    );
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&shot).expect("png"),
    ));
    let mut reader = decoder.read_info().expect("png header");
    let mut pixels = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut pixels).expect("frame");
    let channels = info.color_type.samples();
    let colours: Vec<[u8; 3]> = legend(&dom).into_iter().map(|(_, _, rgb)| rgb).collect();
    let drawn = pixels
        .chunks(channels)
        .filter(|p| colours.iter().any(|c| close([p[0], p[1], p[2]], *c)))
        .count();
    // The legend's own swatches are a few hundred pixels; the ten squares' sides are thousands.
    assert!(drawn > 3000, "{drawn} pixels in the path's colours");
}

#[test]
fn view_refuses_bad_input_as_estimate_does_and_writes_nothing() {
    let dir = tempfile::tempdir().expect("temp dir");
    let gcode = dir.path().join("bad.gcode");
    std::fs::write(&gcode, "G28\nG90\nG1 X1.2.3 Y5\n").expect("write");
    let config = example_machine("cartesian");
    let page = dir.path().join("bad.html");
    let (c, g, p) = (
        config.display().to_string(),
        gcode.display().to_string(),
        page.display().to_string(),
    );
    let estimate = jointspace(&["estimate", "-c", &c, &g]);
    let viewed = jointspace(&["view", "-c", &c, &g, "-o", &p]);
    assert_eq!(viewed.status.code(), Some(1));
    let first = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stderr)
            .lines()
            .next()
            .unwrap_or("")
            .to_string()
    };
    assert!(
        first(&viewed).contains("bad.gcode:3:"),
        "{}",
        first(&viewed)
    );
    assert_eq!(first(&viewed), first(&estimate));
    assert!(!page.exists(), "a failed view leaves no page");
    // A page over an input (the G-code or the config) is refused before anything is planned.
    let good = dir.path().join("good.gcode");
    std::fs::write(&good, "G28\nG1 X10 Y10 Z1 F3000\n").expect("write");
    let copy = dir.path().join("printer.cfg");
    std::fs::copy(&config, &copy).expect("copy config");
    for target in [&good, &copy] {
        let before = std::fs::read(target).expect("read");
        let out = jointspace(&[
            "view",
            "-c",
            &copy.display().to_string(),
            &good.display().to_string(),
            "-o",
            &target.display().to_string(),
        ]);
        assert_eq!(
            out.status.code(),
            Some(1),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(
            std::fs::read(target).expect("read"),
            before,
            "{} untouched",
            target.display()
        );
    }
    let missing = jointspace(&[
        "view",
        "-c",
        "no-such.cfg",
        &good.display().to_string(),
        "-o",
        &p,
    ]);
    assert_eq!(missing.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no-such.cfg"));
    assert!(!page.exists());
}
