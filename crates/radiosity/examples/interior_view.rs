//! Prints what the interior-view rule ([`radiosity::scene::interior`]) finds
//! for a scene: each candidate eye's sight-line shares and the choice.
//! `cargo run --release --example interior_view -- SCENE`.

use radiosity::scene::{self, interior};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let name = std::env::args()
        .nth(1)
        .ok_or("usage: interior_view SCENE")?;
    let scene = scene::load(&name)?;
    let start = std::time::Instant::now();
    let Some(analysis) = interior::analyse(&scene) else {
        println!("{name}: no light or no extent: the framing camera");
        return Ok(());
    };
    println!(
        "{name}: {} surfaces, analysed in {:.3} s; mean escape {:.3}: {}",
        scene.surfaces.len(),
        start.elapsed().as_secs_f64(),
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
            "{}{i:2} eye ({:.2}, {:.2}, {:.2}) fov {:.0}: escape {:.2} back {:.2} view escape {:.2} sight {:.3}",
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
    let c = scene.camera_or_framing();
    println!(
        "camera: {},{},{},{},{},{},0,1,0,{}",
        c.eye.x, c.eye.y, c.eye.z, c.target.x, c.target.y, c.target.z, c.fov_degrees
    );
    Ok(())
}
