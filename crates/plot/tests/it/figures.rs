//! Figures with every layer kind render to a PNG that decodes to the right size with the expected colours,
//! and to well-formed SVG.

use std::fs::File;

use plot::{ColourScale, Figure, Grid, Layer, Legend, Rgb};

use crate::wellformed::check_xml;

fn small_heat_map() -> Figure {
    // 4×3 cells of 10 mm, values = x index; the middle cell of the top row is empty (grey).
    let values = (0..12)
        .map(|i| if i == 9 { None } else { Some((i % 4) as f64) })
        .collect();
    let grid = Grid::new(0.0, 0.0, 10.0, 4, 3, values).expect("12 values");
    let scale = ColourScale {
        min: 0.0,
        max: 3.0,
        label: "value (mm)".into(),
        log: false,
    };
    let mut fig = Figure::new("test heat map & <escapes>");
    fig.width = 420;
    fig.height = 320;
    fig.colour_bar = Some(scale.clone());
    fig.layers.push(Layer::Heatmap {
        grid,
        scale: scale.clone(),
    });
    fig.layers.push(Layer::Circle {
        centre: [20.0, 15.0],
        radius: 10.0,
        colour: Rgb::BLACK,
        width: 2.0,
    });
    fig.layers.push(Layer::Segments {
        segments: vec![[[0.0, 0.0], [40.0, 30.0]], [[40.0, 0.0], [0.0, 30.0]]],
        values: vec![0.0, 3.0],
        scale,
        width: 2.0,
    });
    fig.layers.push(Layer::Points {
        points: vec![[5.0, 5.0]],
        colour: Rgb(255, 0, 0),
        radius_px: 3.0,
    });
    fig.layers.push(Layer::Text {
        at: [1.0, 28.0],
        text: "label".into(),
        colour: Rgb::BLACK,
        size: 12.0,
    });
    fig.legend = Some(Legend {
        entries: vec![("grey: no value".into(), Rgb::NO_DATA)],
    });
    fig
}

fn decode_png(path: &std::path::Path) -> (png::OutputInfo, Vec<u8>) {
    let file = std::io::BufReader::new(File::open(path).expect("png written"));
    let mut reader = png::Decoder::new(file).read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("png size")];
    let info = reader.next_frame(&mut buf).expect("png data");
    buf.truncate(info.buffer_size());
    (info, buf)
}

#[test]
fn heat_map_png_decodes_with_its_colours() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("heat.png");
    small_heat_map().write_png(&path).expect("png");
    let (info, pixels) = decode_png(&path);
    assert_eq!((info.width, info.height), (420, 320));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let has = |c: Rgb| pixels.chunks(3).any(|p| p == [c.0, c.1, c.2]);
    assert!(has(Rgb::NO_DATA), "empty cell drawn grey");
    assert!(
        has(Rgb(68, 1, 84)) && has(Rgb(253, 231, 37)),
        "both ends of the colour map present"
    );
    // Text was rasterised with the bundled font: some pixels are neither white nor a map colour.
    let dark = pixels
        .chunks(3)
        .filter(|p| p.iter().all(|v| *v < 40))
        .count();
    assert!(
        dark > 100,
        "title, labels and outline drawn ({dark} dark pixels)"
    );
    assert!(
        !dir.path().join(".heat.png.tmp").exists(),
        "temporary file renamed away"
    );
}

#[test]
fn heat_map_svg_is_well_formed() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("heat.svg");
    small_heat_map().write_svg(&path).expect("svg");
    let text = std::fs::read_to_string(&path).expect("svg written");
    check_xml(&text).expect("well-formed SVG");
    assert!(text.contains("test heat map &amp; &lt;escapes&gt;"));
    assert!(text.contains(&Rgb::NO_DATA.hex()), "grey cell present");
    assert!(text.contains("<circle") && text.contains("<polyline"));
}

#[test]
fn unusable_sizes_are_errors() {
    let mut fig = small_heat_map();
    fig.width = 10;
    assert!(fig.to_png().is_err() && fig.to_svg().is_err());
}
