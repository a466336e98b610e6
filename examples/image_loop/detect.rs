//! From an image to the four corners the servo takes: a pure-Rust AprilTag detector (`kornia-apriltag`), its
//! corners put in the target's order and in the camera model's pixel convention, and the frames it must not pass on.
//!
//! - **Order.** The detector's homography `H` (rotated by the decoded rotation, so it follows the tag's own
//!   orientation, whatever the tag's orientation in the image) maps tag coordinates `(±1, ±1)` to the image; the
//!   target's corner `P_k` is printed at the tag corner `TAG_CORNERS[k]` ([`crate::render::TagBoard`]), so corner `k`
//!   is `H · TAG_CORNERS[k]`. The quad's own `corners` follow the image (top-right first, whatever the tag's
//!   orientation) and would be mis-ordered as soon as the tag turns.
//! - **Pixels.** The detector reads pixel `(i, j)` as the square `[i, i+1) × [j, j+1)` (pixel centres at `+0.5`);
//!   the camera model, as OpenCV, puts pixel centres at integers: half a pixel is subtracted.
//! - **Sub-pixel.** The detector refines each edge on the full-resolution image (`refine_edges`, on by default) and
//!   the corners are the intersections of the refined lines: sub-pixel already. The edges are fitted as straight
//!   lines in the distorted image, where the lens bends them: 0.22 px median from the truth in the example, 0.04
//!   without the lens.
//! - **Bad frames** ([`BadFrame`]): no tag of the id, more than one, a corner within [`BORDER_PX`] of the image's
//!   edge (the tag partly out of the image: its corner would be guessed from a cut edge), or corners that do not wind
//!   as the target's do seen from its front (a mirrored or mis-ordered detection).

use crate::render::GrayImage;
use kornia_apriltag::family::{TagFamily, TagFamilyKind};
use kornia_apriltag::{AprilTagDecoder, DecodeTagsConfig};
use kornia_image::{Image, ImageSize};
use std::fmt;

/// The tag coordinates of the target's corners `P0 … P3` (the order of `RectangleTarget::points`).
pub const TAG_CORNERS: [(f32, f32); 4] = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];

/// A corner closer than this to the image's edge (px) makes the frame bad: the tag is (or may be) cut.
pub const BORDER_PX: f64 = 3.0;

/// Why a frame gives no corners.
#[derive(Debug, Clone, PartialEq)]
pub enum BadFrame {
    /// No tag of the target's id in the image.
    Lost,
    /// More than one tag of the target's id.
    Ambiguous { count: usize },
    /// A corner outside the image or within [`BORDER_PX`] of its edge.
    PartlyOutside { corner: usize, u: f64, v: f64 },
    /// The corners do not wind as the target's front does (signed area ≤ 0) or are not convex.
    Flipped,
    /// The detector failed on the image.
    Detector(String),
}

impl fmt::Display for BadFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Lost => write!(f, "tag lost"),
            Self::Ambiguous { count } => write!(f, "{count} tags of the target's id"),
            Self::PartlyOutside { corner, u, v } => {
                write!(
                    f,
                    "corner {corner} at ({u:.1}, {v:.1}) px is at or past the image's edge"
                )
            }
            Self::Flipped => write!(f, "corners flipped or not convex"),
            Self::Detector(error) => write!(f, "detector: {error}"),
        }
    }
}

impl std::error::Error for BadFrame {}

/// The cells of tag36h11's tag `id`, row by row (`true` = white), black border included: 8 × 8, from the family's
/// code table and bit layout as the detector has them (the C library's `apriltag_to_image` draws the same).
///
/// # Errors
/// An id outside the family's 587 codes.
pub fn tag36h11_cells(id: u16) -> Result<(usize, Vec<bool>), Box<dyn std::error::Error>> {
    let family = TagFamily::tag36_h11()?;
    let code = *family
        .code_data
        .get(usize::from(id))
        .ok_or_else(|| format!("tag36h11 has no tag {id}"))?;
    let n = family.width_at_border;
    let mut white = vec![false; n * n];
    for bit in 0..family.nbits {
        if code >> (family.nbits - 1 - bit) & 1 == 1 {
            let (column, row) = (family.bit_x[bit] as usize, family.bit_y[bit] as usize);
            white[row * n + column] = true;
        }
    }
    Ok((n, white))
}

/// The detector of one tag36h11 tag in images of one size.
pub struct TagDetector {
    decoder: AprilTagDecoder,
    id: u16,
    image: Image<u8, 1>,
}

impl TagDetector {
    /// A detector of tag36h11's tag `id` in `width × height` images, with the detector's default parameters
    /// (quads found at half resolution, edges refined at full resolution, up to 2 bit errors).
    ///
    /// # Errors
    /// The detector's, for an empty image.
    pub fn new(width: usize, height: usize, id: u16) -> Result<Self, Box<dyn std::error::Error>> {
        let size = ImageSize { width, height };
        let config = DecodeTagsConfig::new(vec![TagFamilyKind::Tag36H11])?;
        Ok(Self {
            decoder: AprilTagDecoder::new(config, size)?,
            id,
            image: Image::from_size_val(size, 0)?,
        })
    }

    /// The target's four corners (px, the camera model's convention, in the order of `RectangleTarget::points`)
    /// found in `frame`, or why there are none.
    pub fn detect(&mut self, frame: &GrayImage) -> Result<[(f64, f64); 4], BadFrame> {
        let (width, height) = (self.image.width(), self.image.height());
        if (frame.width, frame.height) != (width, height) {
            return Err(BadFrame::Detector(format!(
                "a {}×{} image for a {width}×{height} detector",
                frame.width, frame.height
            )));
        }
        self.image.as_slice_mut().copy_from_slice(&frame.pixels);
        self.decoder.clear();
        let detections = self
            .decoder
            .decode(&self.image)
            .map_err(|error| BadFrame::Detector(error.to_string()))?;
        let mut ours = detections
            .iter()
            .filter(|d| d.tag_family_kind == TagFamilyKind::Tag36H11 && d.id == self.id);
        let detection = ours.next().ok_or(BadFrame::Lost)?;
        let others = ours.count();
        if others > 0 {
            return Err(BadFrame::Ambiguous { count: others + 1 });
        }
        let corners = TAG_CORNERS.map(|(x, y)| {
            let p = detection.quad.homography_project(x, y);
            (f64::from(p.x) - 0.5, f64::from(p.y) - 0.5)
        });
        check_corners(&corners, width as f64, height as f64)?;
        Ok(corners)
    }
}

/// The checks of a detection's corners (module docs): inside the image by [`BORDER_PX`], convex, and winding as the
/// target's front does (with y down, `P0 → P1 → P2 → P3` turns clockwise on the screen: every cross product of
/// consecutive edges positive).
pub fn check_corners(corners: &[(f64, f64); 4], width: f64, height: f64) -> Result<(), BadFrame> {
    for (corner, &(u, v)) in corners.iter().enumerate() {
        let inside = |value: f64, size: f64| value >= BORDER_PX && value <= size - 1.0 - BORDER_PX;
        if !(inside(u, width) && inside(v, height)) {
            return Err(BadFrame::PartlyOutside { corner, u, v });
        }
    }
    for k in 0..4 {
        let (a, b, c) = (corners[k], corners[(k + 1) % 4], corners[(k + 2) % 4]);
        let cross = (b.0 - a.0) * (c.1 - b.1) - (b.1 - a.1) * (c.0 - b.0);
        if cross.is_nan() || cross <= 0.0 {
            return Err(BadFrame::Flipped);
        }
    }
    Ok(())
}
