//! Prints what the interior-view rule ([`radiosity::view::interior`]) finds
//! for each scene given: each candidate eye's sight-line shares, the choice
//! and the camera, and the median time of the analysis over `--runs`
//! analyses (BVH build included; default 1).
//! `cargo run --release --example interior_view -- [--runs N] SCENE...`.

use radiosity::scene;
use radiosity::view::{self, interior};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut runs = 1;
    if let Some(i) = args.iter().position(|a| a == "--runs") {
        runs = args
            .get(i + 1)
            .and_then(|n| n.parse::<usize>().ok())
            .filter(|&n| n > 0)
            .ok_or("--runs takes a positive number")?;
        args.drain(i..i + 2);
    }
    if args.is_empty() {
        return Err("usage: interior_view [--runs N] SCENE...".into());
    }
    for name in &args {
        let scene = scene::load(name)?;
        let mut times = Vec::with_capacity(runs);
        let mut analysis = None;
        for _ in 0..runs {
            let start = std::time::Instant::now();
            analysis = interior::analyse(&scene);
            times.push(start.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        let median = times[times.len() / 2];
        let Some(analysis) = analysis else {
            println!("{name}: no light or no extent: the framing camera");
            continue;
        };
        println!(
            "{name}: {} surfaces, analysed in {median:.3} s (median of {runs}); mean escape {:.3}: {}",
            scene.surfaces.len(),
            analysis.escape,
            if analysis.interior {
                "interior"
            } else {
                "seen from outside"
            }
        );
        for (i, c) in analysis.candidates.iter().enumerate() {
            let e = c.camera.eye;
            println!(
                "{}{i:2} eye ({:.2}, {:.2}, {:.2}) fov {:.0}: escape {:.2} back {:.2} view escape {:.2} sight {:.6}",
                if analysis.chosen == Some(i) {
                    "*"
                } else if c.usable() {
                    " "
                } else {
                    "x"
                },
                e.x,
                e.y,
                e.z,
                c.camera.fov_degrees,
                c.escape,
                c.back,
                c.view_escape,
                c.sight
            );
        }
        let c = view::camera_or_framing(&scene);
        println!(
            "camera: {},{},{},{},{},{},0,1,0,{}",
            c.eye.x, c.eye.y, c.eye.z, c.target.x, c.target.y, c.target.z, c.fov_degrees
        );
    }
    Ok(())
}
