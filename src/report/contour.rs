//! Isolines by marching squares.
//!
//! Values on a rectangular grid; each cell's edges crossing the level get a point by linear
//! interpolation, the cell's segments follow the usual 16-case table (saddles resolved by the
//! cell's centre value), and segments are joined into polylines by matching end points so a
//! plot draws few long paths instead of thousands of pieces. Cells with a NaN corner are skipped.

use std::collections::HashMap;

/// Polylines of z(x, y) = level; `z` is y-major: `z[j * nx + i]` at (`x[i]`, `y[j]`).
pub fn isolines(x: &[f64], y: &[f64], z: &[f64], level: f64) -> Vec<Vec<(f64, f64)>> {
    let (nx, ny) = (x.len(), y.len());
    if nx < 2 || ny < 2 || z.len() != nx * ny {
        return Vec::new();
    }
    let at = |i: usize, j: usize| z[j * nx + i];
    // Edge ids: horizontal edge (i, j)-(i+1, j) = 2·(j·nx + i), vertical (i, j)-(i, j+1) = +1.
    let h_edge = |i: usize, j: usize| 2 * (j * nx + i);
    let v_edge = |i: usize, j: usize| 2 * (j * nx + i) + 1;
    let point = |e: usize| -> (f64, f64) {
        let cell = e / 2;
        let (i, j) = (cell % nx, cell / nx);
        if e.is_multiple_of(2) {
            let (z0, z1) = (at(i, j), at(i + 1, j));
            let t = (level - z0) / (z1 - z0);
            (x[i] + t * (x[i + 1] - x[i]), y[j])
        } else {
            let (z0, z1) = (at(i, j), at(i, j + 1));
            let t = (level - z0) / (z1 - z0);
            (x[i], y[j] + t * (y[j + 1] - y[j]))
        }
    };
    let mut segments: Vec<(usize, usize)> = Vec::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let c = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            if c.iter().any(|v| !v.is_finite()) {
                continue;
            }
            let above: Vec<bool> = c.iter().map(|v| *v > level).collect();
            let case = above.iter().enumerate().fold(0, |acc, (k, a)| acc | ((*a as usize) << k));
            // Edges of the cell: bottom, right, top, left.
            let (b, r, t, l) = (h_edge(i, j), v_edge(i + 1, j), h_edge(i, j + 1), v_edge(i, j));
            match case {
                0 | 15 => {}
                1 | 14 => segments.push((l, b)),
                2 | 13 => segments.push((b, r)),
                3 | 12 => segments.push((l, r)),
                4 | 11 => segments.push((r, t)),
                6 | 9 => segments.push((b, t)),
                7 | 8 => segments.push((l, t)),
                5 | 10 => {
                    let centre = 0.25 * c.iter().sum::<f64>();
                    let centre_above = centre > level;
                    // Case 5: corners 0 and 2 above. If the centre is above too they connect.
                    if (case == 5) == centre_above {
                        segments.push((l, t));
                        segments.push((b, r));
                    } else {
                        segments.push((l, b));
                        segments.push((r, t));
                    }
                }
                _ => unreachable!(),
            }
        }
    }
    join(&segments).into_iter().map(|path| path.into_iter().map(point).collect()).collect()
}

/// Joins segments sharing end points into polylines (closed loops repeat their first point).
fn join(segments: &[(usize, usize)]) -> Vec<Vec<usize>> {
    let mut adjacency: HashMap<usize, Vec<usize>> = HashMap::new();
    for (k, &(a, b)) in segments.iter().enumerate() {
        adjacency.entry(a).or_default().push(k);
        adjacency.entry(b).or_default().push(k);
    }
    let mut used = vec![false; segments.len()];
    let mut paths = Vec::new();
    // Start from open ends first (points with a single segment), then the remaining loops.
    let mut starts: Vec<usize> = adjacency.iter().filter(|(_, v)| v.len() == 1).map(|(p, _)| *p).collect();
    starts.sort_unstable();
    let mut loop_starts: Vec<usize> = segments.iter().map(|s| s.0).collect();
    loop_starts.sort_unstable();
    for start in starts.into_iter().chain(loop_starts) {
        let mut path = vec![start];
        let mut cur = start;
        while let Some(&k) = adjacency.get(&cur).and_then(|v| v.iter().find(|&&k| !used[k])) {
            used[k] = true;
            let (a, b) = segments[k];
            cur = if a == cur { b } else { a };
            path.push(cur);
        }
        if path.len() > 1 {
            paths.push(path);
        }
    }
    paths
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize, lo: f64, hi: f64) -> Vec<f64> {
        (0..n).map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64).collect()
    }

    #[test]
    fn circle_is_one_closed_polyline_near_the_unit_circle() {
        let (x, y) = (grid(41, -2.0, 2.0), grid(41, -2.0, 2.0));
        let z: Vec<f64> = y.iter().flat_map(|yy| x.iter().map(move |xx| xx * xx + yy * yy)).collect();
        let lines = isolines(&x, &y, &z, 1.0);
        assert_eq!(lines.len(), 1);
        let l = &lines[0];
        assert_eq!(l.first(), l.last(), "closed");
        for (px, py) in l {
            assert!(((px * px + py * py).sqrt() - 1.0).abs() < 0.01);
        }
    }

    #[test]
    fn plane_gives_a_straight_line_and_out_of_range_gives_nothing() {
        let (x, y) = (grid(11, 0.0, 1.0), grid(7, 0.0, 1.0));
        let z: Vec<f64> = y.iter().flat_map(|_| x.iter().copied()).collect();
        let lines = isolines(&x, &y, &z, 0.33);
        assert_eq!(lines.len(), 1);
        assert_eq!(lines[0].len(), 7);
        for (px, _) in &lines[0] {
            assert!((px - 0.33).abs() < 1e-12);
        }
        assert!(isolines(&x, &y, &z, 5.0).is_empty());
        let mut with_nan = z.clone();
        with_nan[3] = f64::NAN;
        assert!(!isolines(&x, &y, &with_nan, 0.33).is_empty());
    }
}
