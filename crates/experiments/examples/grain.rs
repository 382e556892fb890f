//! The grain of PNG pictures ([`radiosity_experiments::grain`]): the noise
//! left in their smooth parts, 8-bit levels. Every pixel counts as
//! covered but pure black ones (the background).
//!
//! `cargo run --release -p radiosity-experiments --example grain -- A.png ...`

use std::fs::File;

use radiosity_experiments::grain;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for path in std::env::args().skip(1) {
        let decoder = png::Decoder::new(std::io::BufReader::new(File::open(&path)?));
        let mut reader = decoder.read_info()?;
        let mut buffer = vec![0; reader.output_buffer_size().ok_or("picture too large")?];
        let info = reader.next_frame(&mut buffer)?;
        if info.color_type != png::ColorType::Rgb || info.bit_depth != png::BitDepth::Eight {
            return Err(format!("{path}: not 8-bit RGB").into());
        }
        let rgb = &buffer[..info.buffer_size()];
        let luma = grain::luma(rgb);
        let (width, height) = (info.width as usize, info.height as usize);
        match grain::grain(&luma, width, height, &|i| {
            rgb[3 * i..3 * i + 3].iter().any(|c| *c > 0)
        }) {
            Some(g) => println!(
                "{path}: grain p95 {:.2}, worst {:.2} levels over {} smooth tiles",
                g.p95, g.worst, g.tiles
            ),
            None => println!("{path}: no smooth tile"),
        }
    }
    Ok(())
}
