//! From a frame's traced contours to measured objects, in one pass: the per-frame work of
//! object location after OpenCV's edge tracing, which in Python cost more than the tracing.
//!
//! Each contour (whole-pixel points, as OpenCV's findContours traces them) is kept or dropped
//! by its enclosed area and by whether it touches the frame's border; a kept contour's points
//! are moved to the grey-level edge (`outline`, on a sigma-1 smoothing of the object's own
//! region, `smooth`), and its area, centroid and central second moments (its principal axis)
//! are those of the refined outline. The objects
//! come in reading order (`reading_order`), which is how their IDs are numbered.

use crate::alloc;
use crate::error::Result;
use crate::image::{GreyU8, Rect};
use crate::outline::{area_centroid, central_moments, refine_outline, Grey, MIN_POINTS};
use crate::smooth::{gaussian_region, reserve_region};
use crate::Point;

/// Which contours are objects.
#[derive(Clone, Copy, Debug)]
pub struct ContourFilter {
    /// The enclosed area of the traced contour, px^2, inclusive.
    pub min_area: f64,
    /// The largest enclosed area kept, px^2, inclusive.
    pub max_area: f64,
    /// Keep contours whose bounding box touches the frame's border (their centroid is not
    /// the object's).
    pub keep_border: bool,
    /// Move outlines to the grey-level edge (else the traced pixels are the outline).
    pub subpixel: bool,
}

/// One object.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasuredObject {
    /// Its contour's position in the input.
    pub contour: usize,
    /// Enclosed area, px^2, and its centroid, of the (refined) outline.
    pub area: f64,
    pub centroid: Point,
    /// The enclosed area's central second moments over its area, [mu20, mu11, mu02] / area,
    /// px^2 (`central_moments`): the part's principal axis and how elongated it is.
    pub moments: [f64; 3],
    /// The traced contour's bounding box: x, y, width, height (OpenCV's boundingRect).
    pub bbox: [i64; 4],
    pub outline: Vec<Point>,
}

/// The smoothed region around an object the edge search reads: its bounding box widened by
/// the search's reach (3 px) and the bilinear sample's second pixel, and one more to spare
/// (the smoothing itself reads the frame's real pixels around the region).
pub const EDGE_PAD: i64 = 5;

/// The fewest chain points an outline enclosing `min_area` px^2 can have: a closed outline
/// of n points has a perimeter of at most n * sqrt(2), and no shape encloses more than
/// perimeter^2 / (4 pi). Shorter contours are skipped unread.
pub fn fewest_points(min_area: f64) -> f64 {
    (4.0 * std::f64::consts::PI * min_area.max(0.0)).sqrt() / std::f64::consts::SQRT_2
}

/// The objects among `contours` (each a closed polygon of pixel positions), in reading order.
/// OutOfMemory when an outline or the smoothed region around it cannot be allocated.
pub fn measure_contours(
    image: GreyU8<'_>,
    contours: &[&[[i32; 2]]],
    filter: &ContourFilter,
) -> Result<Vec<MeasuredObject>> {
    let shortest = fewest_points(filter.min_area);
    // One thread: the per-frame work is too short for the pool (waking its threads costs as
    // much as they would save).
    let mut buffers = (Vec::new(), Vec::new());
    let mut found = Vec::new();
    for (i, contour) in contours.iter().enumerate() {
        if contour.is_empty() || (contour.len() as f64) < shortest {
            continue;
        }
        if let Some(object) = measure_one(image, i, contour, filter, &mut buffers)? {
            alloc::reserve(&mut found, 1)?;
            found.push(object);
        }
    }
    let centroids = alloc::collect(found.iter().map(|o| o.centroid))?;
    let heights = alloc::collect(found.iter().map(|o| o.bbox[3] as f64))?;
    let mut slots = alloc::collect(found.into_iter().map(Some))?;
    alloc::collect(
        reading_order(&centroids, &heights)?
            .into_iter()
            .filter_map(|i| slots[i].take()),
    )
}

/// One contour, if it is an object (`buffers`: the smoothing's, reused from one to the next).
fn measure_one(
    image: GreyU8<'_>,
    index: usize,
    contour: &[[i32; 2]],
    filter: &ContourFilter,
    buffers: &mut (Vec<f32>, Vec<f32>),
) -> Result<Option<MeasuredObject>> {
    let (w, h) = (image.width as i64, image.height as i64);
    let traced = alloc::collect(contour.iter().map(|p| [p[0] as f64, p[1] as f64]))?;
    let (area, centroid) = area_centroid(&traced);
    if !(filter.min_area <= area && area <= filter.max_area) {
        return Ok(None);
    }
    let bbox = bounding_box(contour);
    let [x, y, bw, bh] = bbox;
    if !filter.keep_border && (x <= 0 || y <= 0 || x + bw >= w || y + bh >= h) {
        return Ok(None);
    }
    let mut object = MeasuredObject {
        contour: index,
        area,
        centroid,
        moments: [0.0; 3],
        bbox,
        outline: traced,
    };
    if filter.subpixel && contour.len() >= MIN_POINTS {
        refine(image, &mut object, buffers)?;
    }
    // Of the outline as it ends (refined, or traced where it could not be): translation
    // does not change central moments, so the region's coordinates would do as well.
    object.moments = central_moments(&object.outline);
    Ok(Some(object))
}

/// Indices of objects in reading order: rows from the top (an object joins a row when its
/// centre is within half the median object height of the row's first), left to right within
/// a row; ties keep their given order.
pub fn reading_order(centroids: &[Point], heights: &[f64]) -> Result<Vec<usize>> {
    let n = centroids.len().min(heights.len());
    if n == 0 {
        return Ok(Vec::new());
    }
    let mut sorted = alloc::collect(heights[..n].iter().copied())?;
    sorted.sort_by(f64::total_cmp);
    let median = if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    };
    let reach = 0.5 * median;
    let mut by_y = alloc::collect(0..n)?;
    by_y.sort_by(|&a, &b| centroids[a][1].total_cmp(&centroids[b][1]));
    let mut row_of = alloc::filled(0usize, n)?;
    let (mut row, mut first_y) = (0, centroids[by_y[0]][1]);
    for &i in &by_y {
        let y = centroids[i][1];
        if (y - first_y).abs() > reach {
            row += 1;
            first_y = y;
        }
        row_of[i] = row;
    }
    by_y.sort_by(|&a, &b| {
        row_of[a]
            .cmp(&row_of[b])
            .then(centroids[a][0].total_cmp(&centroids[b][0]))
    });
    Ok(by_y)
}

/// x, y, width, height of the smallest whole-pixel box holding every point.
fn bounding_box(contour: &[[i32; 2]]) -> [i64; 4] {
    let (mut x0, mut y0) = (i64::MAX, i64::MAX);
    let (mut x1, mut y1) = (i64::MIN, i64::MIN);
    for p in contour {
        let (x, y) = (p[0] as i64, p[1] as i64);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    [x0, y0, x1 - x0 + 1, y1 - y0 + 1]
}

/// The object's outline moved to its edge, with the area and centroid it then encloses (its
/// moments are taken by the caller); left
/// as traced when its region is empty (a contour off the frame).
fn refine(
    image: GreyU8<'_>,
    object: &mut MeasuredObject,
    buffers: &mut (Vec<f32>, Vec<f32>),
) -> Result<()> {
    let (region, scratch) = buffers;
    let (w, h) = (image.width as i64, image.height as i64);
    let [x, y, bw, bh] = object.bbox;
    let rect = Rect {
        x0: (x - EDGE_PAD).clamp(0, w) as usize,
        y0: (y - EDGE_PAD).clamp(0, h) as usize,
        x1: (x + bw + EDGE_PAD).clamp(0, w) as usize,
        y1: (y + bh + EDGE_PAD).clamp(0, h) as usize,
    };
    reserve_region(rect, region, scratch)?;
    if !gaussian_region(image, rect, region, scratch) {
        return Ok(());
    }
    // The search and the centroid work in the region's coordinates (whole-pixel shifts,
    // exact), in place.
    let (ox, oy) = (rect.x0 as f64, rect.y0 as f64);
    let shift = |outline: &mut [Point], dx: f64, dy: f64| {
        outline.iter_mut().for_each(|p| *p = [p[0] + dx, p[1] + dy]);
    };
    shift(&mut object.outline, -ox, -oy);
    let grey = Grey {
        pixels: region,
        width: rect.width(),
        height: rect.height(),
    };
    if refine_outline(grey, &mut object.outline) {
        let (area, [cx, cy]) = area_centroid(&object.outline);
        object.area = area;
        object.centroid = [cx + ox, cy + oy];
    }
    shift(&mut object.outline, ox, oy);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A w x h frame with a bright disc of radius r about c on a dark background, its edge a
    /// smooth ramp.
    fn disc_frame(w: usize, h: usize, c: Point, r: f64) -> Vec<u8> {
        let mut px = vec![0u8; w * h];
        for y in 0..h {
            for x in 0..w {
                let d = (x as f64 - c[0]).hypot(y as f64 - c[1]) - r;
                px[y * w + x] = (60.0 + 120.0 / (1.0 + (d / 0.7).exp())).round() as u8;
            }
        }
        px
    }

    /// The pixel chain just outside the disc (8-connected, whole pixels), like a traced
    /// contour.
    fn traced_ring(c: Point, r: f64) -> Vec<[i32; 2]> {
        let mut ring: Vec<[i32; 2]> = (0..400)
            .map(|k| {
                let t = k as f64 / 400.0 * std::f64::consts::TAU;
                [
                    (c[0] + (r + 1.0) * t.cos()).round() as i32,
                    (c[1] + (r + 1.0) * t.sin()).round() as i32,
                ]
            })
            .collect();
        ring.dedup();
        if ring.first() == ring.last() {
            ring.pop();
        }
        ring
    }

    fn all() -> ContourFilter {
        ContourFilter {
            min_area: 0.0,
            max_area: f64::INFINITY,
            keep_border: false,
            subpixel: true,
        }
    }

    #[test]
    fn a_disc_is_found_at_its_centre_and_its_area() {
        let (w, h, c, r) = (90, 70, [41.3, 36.6], 14.0);
        let px = disc_frame(w, h, c, r);
        let image = GreyU8 {
            pixels: &px,
            width: w,
            height: h,
        };
        let ring = traced_ring(c, r);
        let found = measure_contours(image, &[&ring], &all()).unwrap();
        assert_eq!(found.len(), 1);
        let o = &found[0];
        assert!((o.centroid[0] - c[0]).abs() < 0.03, "{:?}", o.centroid);
        assert!((o.centroid[1] - c[1]).abs() < 0.03, "{:?}", o.centroid);
        assert!((o.area / (std::f64::consts::PI * r * r) - 1.0).abs() < 0.03);
        // A disc's moments: r^2 / 4 each way, none across (no axis).
        let [m20, m11, m02] = o.moments;
        assert!((m20 / (r * r / 4.0) - 1.0).abs() < 0.03, "{:?}", o.moments);
        assert!((m20 - m02).abs() < 0.01 * m20 && m11.abs() < 0.01 * m20);
        assert_eq!(o.moments, crate::outline::central_moments(&o.outline));
        assert_eq!(o.outline.len(), ring.len());
        // The traced box, as OpenCV's boundingRect gives it.
        let xs = ring.iter().map(|p| p[0]);
        assert_eq!(o.bbox[0], xs.clone().min().unwrap() as i64);
        assert_eq!(
            o.bbox[2],
            (xs.clone().max().unwrap() - xs.min().unwrap() + 1) as i64
        );
        // Without the edge search: the traced ring's own area and centroid.
        let plain = measure_contours(
            image,
            &[&ring],
            &ContourFilter {
                subpixel: false,
                ..all()
            },
        )
        .unwrap();
        let traced: Vec<Point> = ring.iter().map(|p| [p[0] as f64, p[1] as f64]).collect();
        let (area, centre) = area_centroid(&traced);
        assert_eq!((plain[0].area, plain[0].centroid), (area, centre));
        assert!(plain[0].area > o.area);
    }

    #[test]
    fn an_ellipse_s_axis_is_found_at_its_angle() {
        // A 2:1 ellipse (semi-axes 24 and 12 px) at 30 degrees from +x towards +y, its edge
        // a smooth ramp; the traced chain a pixel outside it.
        let (w, h, c) = (100, 90, [50.4, 44.7]);
        let (a, b, t) = (24.0, 12.0, 30f64.to_radians());
        let (s, co) = t.sin_cos();
        let local = |x: f64, y: f64| {
            let (dx, dy) = (x - c[0], y - c[1]);
            (co * dx + s * dy, -s * dx + co * dy)
        };
        let px: Vec<u8> = (0..w * h)
            .map(|i| {
                let (u, v) = local((i % w) as f64, (i / w) as f64);
                // Distance to the edge to first order: the implicit function over its gradient.
                let f = (u / a).powi(2) + (v / b).powi(2) - 1.0;
                let g = 2.0 * (u * u / a.powi(4) + v * v / b.powi(4)).sqrt();
                let d = f / g.max(1e-9);
                (60.0 + 120.0 / (1.0 + (d / 0.7).exp())).round() as u8
            })
            .collect();
        let image = GreyU8 {
            pixels: &px,
            width: w,
            height: h,
        };
        let mut ring: Vec<[i32; 2]> = (0..600)
            .map(|k| {
                let q = k as f64 / 600.0 * std::f64::consts::TAU;
                let (u, v) = ((a + 1.0) * q.cos(), (b + 1.0) * q.sin());
                [
                    (c[0] + co * u - s * v).round() as i32,
                    (c[1] + s * u + co * v).round() as i32,
                ]
            })
            .collect();
        ring.dedup();
        if ring.first() == ring.last() {
            ring.pop();
        }
        let o = &measure_contours(image, &[&ring], &all()).unwrap()[0];
        let [m20, m11, m02] = o.moments;
        let axis = 0.5 * (2.0 * m11).atan2(m20 - m02);
        assert!((axis.to_degrees() - 30.0).abs() < 0.1, "{:?}", o.moments);
        // Variances a^2 / 4 and b^2 / 4 (the outline a little inside the edge).
        let half = (0.25 * (m20 - m02).powi(2) + m11 * m11).sqrt();
        let mean = 0.5 * (m20 + m02);
        assert!(((mean + half) / (a * a / 4.0) - 1.0).abs() < 0.02);
        assert!(((mean - half) / (b * b / 4.0) - 1.0).abs() < 0.02);
    }

    #[test]
    fn a_frame_of_discs_is_each_disc_measured_alone() {
        // Twelve discs, their region buffer reused from one to the next.
        let (w, h) = (320, 240);
        let centres: Vec<Point> = (0..12)
            .map(|k| [40.3 + 75.0 * (k % 4) as f64, 45.6 + 72.0 * (k / 4) as f64])
            .collect();
        let mut px = vec![60u8; w * h];
        for c in &centres {
            let one = disc_frame(w, h, *c, 18.0);
            for (p, q) in px.iter_mut().zip(&one) {
                *p = (*p).max(*q);
            }
        }
        let image = GreyU8 {
            pixels: &px,
            width: w,
            height: h,
        };
        let rings: Vec<Vec<[i32; 2]>> = centres.iter().map(|c| traced_ring(*c, 18.0)).collect();
        let all_rings: Vec<&[[i32; 2]]> = rings.iter().map(|r| r.as_slice()).collect();
        let together = measure_contours(image, &all_rings, &all()).unwrap();
        assert_eq!(together.len(), 12);
        for o in &together {
            let alone = measure_contours(image, &[&rings[o.contour]], &all()).unwrap();
            assert_eq!(
                (o.area, o.centroid, &o.outline),
                (alone[0].area, alone[0].centroid, &alone[0].outline)
            );
        }
        // Reading order: rows of four, left to right.
        let order: Vec<usize> = together.iter().map(|o| o.contour).collect();
        assert_eq!(order, (0..12).collect::<Vec<_>>());
    }

    #[test]
    fn discs_are_found_to_a_hundredth_of_a_pixel() {
        // 100 discs of random centre and radius (8-22 px), edges blurred as a lens does,
        // sensor noise of +-3 grey levels, whole-pixel rings traced a pixel outside.
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let (w, h) = (90, 80);
        let (mut centre_err, mut radius_err) = (0.0, 0.0);
        for _ in 0..100 {
            let c = [40.0 + 5.0 * rnd(), 38.0 + 5.0 * rnd()];
            let r = 8.0 + 14.0 * rnd();
            let px: Vec<u8> = (0..w * h)
                .map(|i| {
                    let d = ((i % w) as f64 - c[0]).hypot((i / w) as f64 - c[1]) - r;
                    (60.0 + 120.0 / (1.0 + (d / 0.7).exp()) + 6.0 * (rnd() - 0.5)).round() as u8
                })
                .collect();
            let image = GreyU8 {
                pixels: &px,
                width: w,
                height: h,
            };
            let ring = traced_ring(c, r);
            let o = &measure_contours(image, &[&ring], &all()).unwrap()[0];
            centre_err += (o.centroid[0] - c[0]).hypot(o.centroid[1] - c[1]) / 100.0;
            radius_err += ((o.area / std::f64::consts::PI).sqrt() - r) / 100.0;
        }
        // The centres to 0.01 px (the parabola it replaced: 0.04 px); the outline a few
        // hundredths of a pixel inside the edge (the smoothing rounds a disc's edge inward).
        assert!(centre_err < 0.015, "{centre_err}");
        assert!(radius_err.abs() < 0.06, "{radius_err}");
    }

    #[test]
    fn contours_are_filtered_by_area_length_and_border() {
        let (w, h) = (60, 50);
        let px = vec![100u8; w * h];
        let image = GreyU8 {
            pixels: &px,
            width: w,
            height: h,
        };
        let square = |x: i32, y: i32, s: i32| -> Vec<[i32; 2]> {
            let mut v = Vec::new();
            for i in 0..s {
                v.push([x + i, y]);
            }
            for i in 0..s {
                v.push([x + s, y + i]);
            }
            for i in 0..s {
                v.push([x + s - i, y + s]);
            }
            for i in 0..s {
                v.push([x, y + s - i]);
            }
            v
        };
        let (inner, touching, small) = (square(10, 10, 20), square(0, 5, 20), square(40, 30, 3));
        let found = measure_contours(image, &[&touching, &small, &inner, &[]], &all()).unwrap();
        // The border square and the empty contour are dropped; the small one is kept (below
        // the big one: second in reading order).
        assert_eq!(
            found.iter().map(|o| o.contour).collect::<Vec<_>>(),
            vec![2, 1]
        );
        let keep = ContourFilter {
            keep_border: true,
            min_area: 100.0,
            ..all()
        };
        let found = measure_contours(image, &[&touching, &small, &inner], &keep).unwrap();
        assert_eq!(
            found.iter().map(|o| o.contour).collect::<Vec<_>>(),
            vec![0, 2]
        );
        // A flat frame has no edge: the outline stays as traced, area 400.
        assert_eq!(found[1].area, 400.0);
        assert_eq!(found[1].centroid, [20.0, 20.0]);
        let capped = ContourFilter {
            max_area: 399.0,
            ..all()
        };
        assert_eq!(
            measure_contours(image, &[&inner], &capped).unwrap().len(),
            0
        );
    }

    #[test]
    fn reading_order_is_rows_from_the_top_then_left_to_right() {
        // Two rows (heights 10: a row spans 5 px), given out of order.
        let centroids = [
            [50.0, 31.0],
            [10.0, 12.0],
            [30.0, 9.0],
            [5.0, 33.0],
            [70.0, 10.0],
        ];
        let heights = [10.0; 5];
        assert_eq!(
            reading_order(&centroids, &heights).unwrap(),
            vec![1, 2, 4, 3, 0]
        );
        assert!(reading_order(&[], &[]).unwrap().is_empty());
    }

    #[test]
    fn contours_off_the_frame_do_not_panic() {
        let px = vec![0u8; 20 * 20];
        let image = GreyU8 {
            pixels: &px,
            width: 20,
            height: 20,
        };
        let far: Vec<[i32; 2]> = (0..40).map(|i| [100 + i % 10, 100 + i / 10]).collect();
        let keep = ContourFilter {
            keep_border: true,
            ..all()
        };
        let found = measure_contours(image, &[&far], &keep).unwrap();
        assert_eq!(found.len(), 1);
        assert!(found[0].centroid.iter().all(|v| v.is_finite()));
    }
}
