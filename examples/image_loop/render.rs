//! The simulated camera image: the target printed as an AprilTag, seen through the calibrated camera with its lens
//! distortion, with sensor integration, a little optical blur, vignetting and pixel noise.
//!
//! Each pixel `(u, v)` (OpenCV's convention: integer coordinates at pixel centres, as the camera model's `cx, cy`) is
//! integrated over `S × S` sub-pixel samples. A sample's ray is the undistorted normalised point
//! `(x, y) = normalized_of(u, v)` ([`CalibratedCamera::normalized_of`], through the lens model), computed once per
//! camera; each frame intersects the ray `(x, y, 1)` with the target's plane `z = 0` (object frame) and reads the
//! printed albedo there. The pixel's mean albedo times the vignetting, blurred by a 3 × 3 binomial kernel, plus
//! Gaussian noise, is quantised to 8 bits.

use nalgebra::Isometry3;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use servostack::camera::CalibratedCamera;
use servostack::target::RectangleTarget;

/// An 8-bit grey image, row-major, `width × height` pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct GrayImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u8>,
}

impl GrayImage {
    /// A black image.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            pixels: vec![0; width * height],
        }
    }
}

/// Albedo of the tag's black ink, the white paper, the table the target lies on (two tones of a 4 cm checker), and
/// the back of the board.
const INK: f32 = 0.06;
const PAPER: f32 = 0.9;
const TABLE: [f32; 2] = [0.3, 0.42];
const TABLE_SQUARE_M: f64 = 0.04;
const BOARD_BACK: f32 = 0.5;

/// The printed target: a tag's `n × n` cells (the black border and the data bits) stretched over the target's
/// rectangle, so that the outer corners of the tag's black square are the target's four corners, on a sheet of white
/// paper `margin` cells wide around it, on a checkered table.
///
/// The tag's cell `(column, row)` covers `x ∈ [−w/2 + column·w/n, …]`, `y ∈ [−h/2 + row·h/n, …]` of the object frame:
/// the tag's top-left corner (its tag coordinates `(−1, −1)`) is the target's `P0 = (−w/2, −h/2)`, its columns run
/// along x and its rows along y. AprilTag decoding reads the cells through the homography of the four corners, so a
/// tag stretched to a rectangle decodes as a square one does.
#[derive(Debug, Clone)]
pub struct TagBoard {
    cells: usize,
    white: Vec<bool>,
    half_width: f64,
    half_height: f64,
    margin: f64,
}

impl TagBoard {
    /// The tag of `cells × cells` cells (`white[row · cells + column]`) printed over `target`, with `margin` cells of
    /// white paper around it.
    pub fn new(target: &RectangleTarget, cells: usize, white: Vec<bool>, margin: f64) -> Self {
        assert_eq!(white.len(), cells * cells, "one entry per cell");
        Self {
            cells,
            white,
            half_width: 0.5 * target.width(),
            half_height: 0.5 * target.height(),
            margin,
        }
    }

    /// The albedo at `(x, y)` (m) of the target's plane, seen from its front.
    fn albedo(&self, x: f64, y: f64) -> f32 {
        let n = self.cells as f64;
        // Cell coordinates: 0 at the black square's left (top) edge, n at its right (bottom) edge.
        let column = (x + self.half_width) / (2.0 * self.half_width) * n;
        let row = (y + self.half_height) / (2.0 * self.half_height) * n;
        if (0.0..n).contains(&column) && (0.0..n).contains(&row) {
            let cell = row as usize * self.cells + column as usize;
            return if self.white[cell] { PAPER } else { INK };
        }
        let sheet = -self.margin..n + self.margin;
        if sheet.contains(&column) && sheet.contains(&row) {
            return PAPER;
        }
        let parity = (x / TABLE_SQUARE_M).floor() as i64 + (y / TABLE_SQUARE_M).floor() as i64;
        TABLE[parity.rem_euclid(2) as usize]
    }
}

/// The renderer of one calibrated camera: the rays of every sub-pixel sample, computed once.
#[derive(Debug)]
pub struct Renderer {
    width: usize,
    height: usize,
    samples: usize,
    /// `(x, y)` of each sample, pixel by pixel (row-major), `samples²` per pixel; NaN where the lens model does not
    /// undistort.
    rays: Vec<[f32; 2]>,
    /// The vignetting of each pixel, `0.75 + 0.25 cos⁴ θ`.
    shading: Vec<f32>,
    noise_sigma: f32,
    rng: StdRng,
    /// Per-pixel radiance and the blur's intermediate row pass.
    radiance: Vec<f32>,
    blurred: Vec<f32>,
}

impl Renderer {
    /// A renderer for `camera`'s image (its width and height), `samples × samples` samples per pixel, Gaussian pixel
    /// noise of standard deviation `noise_sigma` grey levels drawn from `seed`.
    pub fn new(camera: &CalibratedCamera, samples: usize, noise_sigma: f32, seed: u64) -> Self {
        let (width, height) = (
            camera.intrinsics.width() as usize,
            camera.intrinsics.height() as usize,
        );
        let samples = samples.max(1);
        let mut rays = Vec::with_capacity(width * height * samples * samples);
        let mut shading = Vec::with_capacity(width * height);
        let offset = |k: usize| (k as f64 + 0.5) / samples as f64 - 0.5;
        for v in 0..height {
            for u in 0..width {
                for b in 0..samples {
                    for a in 0..samples {
                        let (su, sv) = (u as f64 + offset(a), v as f64 + offset(b));
                        rays.push(match camera.normalized_of(su, sv) {
                            Ok((x, y)) => [x as f32, y as f32],
                            Err(_) => [f32::NAN; 2],
                        });
                    }
                }
                let cos2 = match camera.normalized_of(u as f64, v as f64) {
                    Ok((x, y)) => 1.0 / (1.0 + x * x + y * y),
                    Err(_) => 0.0,
                };
                shading.push(0.75 + 0.25 * (cos2 * cos2) as f32);
            }
        }
        Self {
            width,
            height,
            samples,
            rays,
            shading,
            noise_sigma,
            rng: StdRng::seed_from_u64(seed),
            radiance: vec![0.0; width * height],
            blurred: vec![0.0; width * height],
        }
    }

    /// The image size (px).
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Renders `board` seen from the camera at `c_from_o` (the target's pose in the camera frame, ViSP `cMo`) into
    /// `image` (resized to the camera's size).
    pub fn render(&mut self, board: &TagBoard, c_from_o: &Isometry3<f64>, image: &mut GrayImage) {
        let o_from_c = c_from_o.inverse();
        let rotation = o_from_c.rotation.to_rotation_matrix();
        let r = rotation.matrix();
        // The optical centre in the object frame; the front of the board (the side the camera sees at its goal) is
        // z < 0.
        let centre = o_from_c.translation.vector;
        let front = centre.z < 0.0;
        let per_pixel = self.samples * self.samples;
        let weight = 1.0 / per_pixel as f32;
        for (pixel, (radiance, shading)) in self.radiance.iter_mut().zip(&self.shading).enumerate()
        {
            let mut sum = 0.0_f32;
            for &[x, y] in &self.rays[pixel * per_pixel..(pixel + 1) * per_pixel] {
                let (x, y) = (f64::from(x), f64::from(y));
                // The ray's direction in the object frame; it meets z = 0 ahead of the camera when s > 0.
                let dx = r[(0, 0)] * x + r[(0, 1)] * y + r[(0, 2)];
                let dy = r[(1, 0)] * x + r[(1, 1)] * y + r[(1, 2)];
                let dz = r[(2, 0)] * x + r[(2, 1)] * y + r[(2, 2)];
                let s = -centre.z / dz;
                sum += if !(s > 0.0 && s.is_finite()) {
                    TABLE[0] // no plane there (or no ray): a far wall
                } else if front {
                    board.albedo(centre.x + s * dx, centre.y + s * dy)
                } else {
                    BOARD_BACK
                };
            }
            *radiance = sum * weight * shading;
        }
        self.blur();
        image.width = self.width;
        image.height = self.height;
        image.pixels.resize(self.width * self.height, 0);
        for (out, value) in image.pixels.iter_mut().zip(&self.radiance) {
            let noisy = 255.0 * value + self.noise_sigma * gaussian(&mut self.rng);
            *out = noisy.round().clamp(0.0, 255.0) as u8;
        }
    }

    /// The 3 × 3 binomial blur `[1 2 1]/4` along rows then columns, in place on `radiance` (edges replicated).
    fn blur(&mut self) {
        let (w, h) = (self.width, self.height);
        for v in 0..h {
            let row = &self.radiance[v * w..(v + 1) * w];
            for u in 0..w {
                let (l, r) = (row[u.saturating_sub(1)], row[(u + 1).min(w - 1)]);
                self.blurred[v * w + u] = 0.25 * (l + 2.0 * row[u] + r);
            }
        }
        for v in 0..h {
            let (up, down) = (v.saturating_sub(1), (v + 1).min(h - 1));
            for u in 0..w {
                let b = &self.blurred;
                self.radiance[v * w + u] =
                    0.25 * (b[up * w + u] + 2.0 * b[v * w + u] + b[down * w + u]);
            }
        }
    }
}

/// A standard normal draw (Box–Muller).
fn gaussian(rng: &mut StdRng) -> f32 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2: f64 = rng.random();
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()) as f32
}
