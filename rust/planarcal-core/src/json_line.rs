//! The production loop's output: one frame as one compact JSON line,
//! {"frame", "t", "coords", "objects": [{"id", "px", "mm", "std_mm", "angle_deg"}, ...]},
//! the objects by ID; "coords" names the frame of reference of "mm" and "angle_deg"
//! ("board" or "robot").

use std::fmt::Write;

use crate::Point;

/// One frame's tracked objects, borrowed: entry k of each slice belongs to `ids[k]`.
#[derive(Debug, Clone, Copy)]
pub struct FrameObjects<'a> {
    /// The frame's index in the stream.
    pub index: i64,
    /// Its time, s.
    pub time: f64,
    /// The objects' track IDs.
    pub ids: &'a [i64],
    /// Their centroids in the image, px.
    pub centroids_px: &'a [Point],
    /// Their positions on the plane, mm.
    pub world_mm: &'a [Point],
    /// Their positions' 1-sigma errors, mm.
    pub std_mm: &'a [f64],
    /// Their orientations in the output frame, degrees in [-90, 90) (not finite: none).
    pub angles_deg: &'a [f64],
    /// The frame of reference of `world_mm` and `angles_deg` ("board" or "robot").
    pub coords: &'a str,
}

/// The slices of a `FrameObjects` do not all have one entry per ID.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "one centroid, position, std and angle per id ({ids}), got {centroids}, {positions}, \
     {stds} and {angles}"
)]
pub struct ObjectCountMismatch {
    /// IDs given.
    pub ids: usize,
    /// Centroids given.
    pub centroids: usize,
    /// Positions given.
    pub positions: usize,
    /// Standard deviations given.
    pub stds: usize,
    /// Angles given.
    pub angles: usize,
}

/// Decimals written: positions to 1e-3 px and 1e-4 mm, errors to 1e-5 mm, the time to the
/// microsecond.
const PX_DECIMALS: usize = 3;
const MM_DECIMALS: usize = 4;
const STD_DECIMALS: usize = 5;
const TIME_DECIMALS: usize = 6;
const ANGLE_DECIMALS: usize = 2;

impl FrameObjects<'_> {
    /// The frame's JSON line (no newline): the objects sorted by ID (equal IDs keep their
    /// order), a value that is not finite written as null.
    pub fn json_line(&self) -> Result<String, ObjectCountMismatch> {
        let n = self.ids.len();
        if self.centroids_px.len() != n
            || self.world_mm.len() != n
            || self.std_mm.len() != n
            || self.angles_deg.len() != n
        {
            return Err(ObjectCountMismatch {
                ids: n,
                centroids: self.centroids_px.len(),
                positions: self.world_mm.len(),
                stds: self.std_mm.len(),
                angles: self.angles_deg.len(),
            });
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&k| self.ids[k]);
        let mut line = String::with_capacity(48 + 96 * n);
        // Writing to a String cannot fail: the results of write! are ignored.
        let _ = write!(line, "{{\"frame\":{},\"t\":", self.index);
        number(&mut line, self.time, TIME_DECIMALS);
        line.push_str(",\"coords\":");
        string(&mut line, self.coords);
        line.push_str(",\"objects\":[");
        for (i, &k) in order.iter().enumerate() {
            if i > 0 {
                line.push(',');
            }
            let _ = write!(line, "{{\"id\":{},\"px\":", self.ids[k]);
            pair(&mut line, self.centroids_px[k], PX_DECIMALS);
            line.push_str(",\"mm\":");
            pair(&mut line, self.world_mm[k], MM_DECIMALS);
            line.push_str(",\"std_mm\":");
            number(&mut line, self.std_mm[k], STD_DECIMALS);
            line.push_str(",\"angle_deg\":");
            number(&mut line, self.angles_deg[k], ANGLE_DECIMALS);
            line.push('}');
        }
        line.push_str("]}");
        Ok(line)
    }
}

/// `v` to `decimals` places, or null if it is not finite (JSON has no NaN or infinity).
fn number(line: &mut String, v: f64, decimals: usize) {
    let _ = if v.is_finite() {
        write!(line, "{v:.decimals$}")
    } else {
        write!(line, "null")
    };
}

/// `text` as a JSON string (quotes, backslashes and control characters escaped).
fn string(line: &mut String, text: &str) {
    line.push('"');
    for c in text.chars() {
        match c {
            '"' => line.push_str("\\\""),
            '\\' => line.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(line, "\\u{:04x}", c as u32);
            }
            c => line.push(c),
        }
    }
    line.push('"');
}

/// [x, y], each as `number`.
fn pair(line: &mut String, p: Point, decimals: usize) {
    line.push('[');
    number(line, p[0], decimals);
    line.push(',');
    number(line, p[1], decimals);
    line.push(']');
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame<'a>(
        ids: &'a [i64],
        px: &'a [Point],
        mm: &'a [Point],
        std: &'a [f64],
        angles: &'a [f64],
    ) -> FrameObjects<'a> {
        FrameObjects {
            index: 17,
            time: 1.25,
            ids,
            centroids_px: px,
            world_mm: mm,
            std_mm: std,
            angles_deg: angles,
            coords: "board",
        }
    }

    #[test]
    fn finite_values_are_written_to_their_decimals() {
        let line = frame(
            &[3],
            &[[12.34567, -0.5]],
            &[[100.0, 2.000049]],
            &[0.0123456],
            &[-12.345],
        )
        .json_line()
        .unwrap(); // ok: test-only, matching lengths
        assert_eq!(
            line,
            "{\"frame\":17,\"t\":1.250000,\"coords\":\"board\",\"objects\":[{\"id\":3,\
             \"px\":[12.346,-0.500],\"mm\":[100.0000,2.0000],\"std_mm\":0.01235,\
             \"angle_deg\":-12.35}]}"
        );
    }

    #[test]
    fn values_that_are_not_finite_are_null() {
        let mut f = frame(
            &[0],
            &[[f64::NAN, 1.0]],
            &[[f64::INFINITY, f64::NEG_INFINITY]],
            &[f64::NAN],
            &[f64::NAN],
        );
        f.coords = "a \"quoted\\ name\n";
        f.time = f64::NAN;
        f.index = -1;
        assert_eq!(
            f.json_line().unwrap(), // ok: test-only
            "{\"frame\":-1,\"t\":null,\"coords\":\"a \\\"quoted\\\\ name\\u000a\",\
             \"objects\":[{\"id\":0,\"px\":[null,1.000],\"mm\":[null,null],\"std_mm\":null,\
             \"angle_deg\":null}]}"
        );
    }

    #[test]
    fn objects_are_sorted_by_id() {
        let line = frame(
            &[9, -2, 4],
            &[[9.0, 9.0], [2.0, 2.0], [4.0, 4.0]],
            &[[0.0; 2]; 3],
            &[0.0; 3],
            &[0.0; 3],
        )
        .json_line()
        .unwrap(); // ok: test-only
        let at = |s: &str| line.find(s).unwrap(); // ok: test-only
        assert!(at("\"id\":-2,\"px\":[2.000") < at("\"id\":4,\"px\":[4.000"));
        assert!(at("\"id\":4,") < at("\"id\":9,\"px\":[9.000"));
    }

    #[test]
    fn an_empty_frame_has_no_objects() {
        assert_eq!(
            frame(&[], &[], &[], &[], &[]).json_line().unwrap(), // ok: test-only
            "{\"frame\":17,\"t\":1.250000,\"coords\":\"board\",\"objects\":[]}"
        );
    }

    #[test]
    fn one_entry_per_id_is_required() {
        let err = frame(&[1, 2], &[[0.0; 2]; 2], &[[0.0; 2]], &[0.0; 2], &[0.0; 2])
            .json_line()
            .unwrap_err(); // ok: test-only
        assert_eq!(
            err.to_string(),
            "one centroid, position, std and angle per id (2), got 2, 1, 2 and 2"
        );
    }
}
