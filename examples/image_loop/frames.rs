//! Annotated frames as PNG: the camera image in grey, the detected corners joined in the target's order (green, `P0`
//! marked by a red square), and the desired corners (yellow crosses) the servo drives them to.

use crate::render::GrayImage;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

const GREEN: [u8; 3] = [40, 220, 40];
const RED: [u8; 3] = [240, 40, 40];
const YELLOW: [u8; 3] = [250, 210, 0];

/// An RGB canvas over a grey image.
struct Canvas {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn put(&mut self, u: i64, v: i64, colour: [u8; 3]) {
        if (0..self.width as i64).contains(&u) && (0..self.height as i64).contains(&v) {
            let at = 3 * (v as usize * self.width + u as usize);
            self.rgb[at..at + 3].copy_from_slice(&colour);
        }
    }

    /// A line from `a` to `b` (px), one dot per pixel along the longer axis.
    fn line(&mut self, a: (f64, f64), b: (f64, f64), colour: [u8; 3]) {
        let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as usize;
        for k in 0..=steps {
            let t = k as f64 / steps as f64;
            let (u, v) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            self.put(u.round() as i64, v.round() as i64, colour);
        }
    }

    fn cross(&mut self, (u, v): (f64, f64), colour: [u8; 3]) {
        self.line((u - 5.0, v - 5.0), (u + 5.0, v + 5.0), colour);
        self.line((u - 5.0, v + 5.0), (u + 5.0, v - 5.0), colour);
    }

    fn square(&mut self, (u, v): (f64, f64), colour: [u8; 3]) {
        let corners =
            [(-4.0, -4.0), (4.0, -4.0), (4.0, 4.0), (-4.0, 4.0)].map(|(a, b)| (u + a, v + b));
        for k in 0..4 {
            self.line(corners[k], corners[(k + 1) % 4], colour);
        }
    }
}

/// Writes `image` to `path` as an RGB PNG with the detected corners (if any) and the desired ones drawn.
///
/// # Errors
/// File and encoder errors.
pub fn write_annotated(
    path: &Path,
    image: &GrayImage,
    detected: Option<&[(f64, f64); 4]>,
    desired: &[(f64, f64); 4],
) -> Result<(), Box<dyn std::error::Error>> {
    let mut canvas = Canvas {
        width: image.width,
        height: image.height,
        rgb: image.pixels.iter().flat_map(|&g| [g, g, g]).collect(),
    };
    for &corner in desired {
        canvas.cross(corner, YELLOW);
    }
    if let Some(corners) = detected {
        for k in 0..4 {
            canvas.line(corners[k], corners[(k + 1) % 4], GREEN);
        }
        canvas.square(corners[0], RED);
    }
    let mut encoder = png::Encoder::new(
        BufWriter::new(File::create(path)?),
        image.width as u32,
        image.height as u32,
    );
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(&canvas.rgb)?;
    Ok(())
}
