//! Pictures checked by statistics, never byte for byte: the Cornell box's
//! red wall (on the left in its standard view) is redder than its green
//! wall, and the picture is neither black nor saturated.

use radiosity::app::{self, ImageJob, Job};
use radiosity::final_gather::FinalGather;
use radiosity::render::Exposure;
use radiosity::solver::Settings;

fn decode(path: &std::path::Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buffer.truncate(info.buffer_size());
    (info.width, info.height, buffer)
}

#[test]
fn cornell_box_red_wall_is_redder_and_exposure_is_sane() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cornell.png");
    let job = Job {
        scene: "cornell".into(),
        settings: Settings {
            converge: 0.05,
            ..Settings::wallace89()
        },
        patch_size: None,
        element_size: None,
        final_gather: FinalGather::Off,
        image: Some(ImageJob {
            path: path.clone(),
            width: 96,
            height: 96,
            camera: None,
            supersampling: 2,
            exposure: Exposure::Auto { ev: 0.0 },
            ambient: true,
        }),
        vertices_csv: None,
        stats_json: None,
        load: Default::default(),
        bake: None,
        ply: None,
        sensors: None,
        max_memory: None,
    };
    app::run(&job, &mut ()).unwrap();
    let (w, h, rgb) = decode(&path);
    assert_eq!((w, h), (96, 96));
    let pixel = |x: u32, y: u32| {
        let i = 3 * (y * w + x) as usize;
        [rgb[i] as f64, rgb[i + 1] as f64, rgb[i + 2] as f64]
    };
    // Mean of red minus green over a band of columns at mid height.
    let red_minus_green = |x0: u32, x1: u32| {
        let mut sum = 0.0;
        let mut n = 0.0;
        for y in h / 4..3 * h / 4 {
            for x in x0..x1 {
                let [r, g, _] = pixel(x, y);
                sum += r - g;
                n += 1.0;
            }
        }
        sum / n
    };
    let left = red_minus_green(0, w / 4);
    let right = red_minus_green(3 * w / 4, w);
    assert!(left > 30.0, "left wall not red: mean r - g = {left}");
    assert!(right < -30.0, "right wall not green: mean r - g = {right}");

    let count = (w * h) as f64;
    let luma: Vec<f64> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let [r, g, b] = pixel(x, y);
            0.2126 * r + 0.7152 * g + 0.0722 * b
        })
        .collect();
    let mean = luma.iter().sum::<f64>() / count;
    let saturated = luma.iter().filter(|l| **l >= 254.0).count() as f64 / count;
    let black = luma.iter().filter(|l| **l <= 1.0).count() as f64 / count;
    assert!((50.0..200.0).contains(&mean), "mean luma {mean}");
    assert!(saturated < 0.05, "saturated fraction {saturated}");
    assert!(black < 0.2, "black fraction {black}");
}
