//! Which cross on the scan is which pose: the pattern's nominal cross centres (the printer's X/Y, from the
//! configured geometry) under the similarity that lays most of them on found crosses, with or without a mirror
//! (a print scanned face down). Every pair of far-apart nominal centres against every ordered pair of found ones
//! proposes a similarity; the one that lays the most centres within a tolerance of a found cross wins, and is
//! refined by least squares over its matches. Robust to missing and extra crosses, any rotation and an unknown
//! scale.

/// `p ↦ scale · R(rotation) · M · p + translation`, M mirroring y when `mirrored` (mm to pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    pub scale: f64,
    pub rotation: f64,
    pub mirrored: bool,
    pub translation: [f64; 2],
}

impl Similarity {
    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let y = if self.mirrored { -p[1] } else { p[1] };
        let (s, c) = self.rotation.sin_cos();
        [
            self.scale * (c * p[0] - s * y) + self.translation[0],
            self.scale * (s * p[0] + c * y) + self.translation[1],
        ]
    }

    /// The direction (unit) a printer direction `d` has on the scan.
    pub fn direction(&self, d: [f64; 2]) -> [f64; 2] {
        let o = self.apply([0.0, 0.0]);
        let e = self.apply(d);
        let l = (e[0] - o[0]).hypot(e[1] - o[1]);
        [(e[0] - o[0]) / l, (e[1] - o[1]) / l]
    }
}

/// The poses' matches: for each pose, the found cross laid on it (index), if any.
#[derive(Debug, Clone, PartialEq)]
pub struct Matching {
    pub similarity: Similarity,
    pub assigned: Vec<Option<usize>>,
    /// The largest distance of a matched cross from its pose under the similarity (mm).
    pub worst_mm: f64,
}

/// The tolerance (mm) within which a found cross is taken for a pose: under half of the closest two poses'
/// distance, and at most 6 mm.
fn tolerance(nominal: &[[f64; 2]]) -> f64 {
    let mut closest = f64::INFINITY;
    for (i, a) in nominal.iter().enumerate() {
        for b in &nominal[i + 1..] {
            closest = closest.min((a[0] - b[0]).hypot(a[1] - b[1]));
        }
    }
    (0.45 * closest).min(6.0)
}

/// The similarity mapping `a0 → b0` and `a1 → b1`.
fn through_pair(a: [[f64; 2]; 2], b: [[f64; 2]; 2], mirrored: bool) -> Option<Similarity> {
    let m = |p: [f64; 2]| if mirrored { [p[0], -p[1]] } else { p };
    let (a0, a1) = (m(a[0]), m(a[1]));
    let da = [a1[0] - a0[0], a1[1] - a0[1]];
    let db = [b[1][0] - b[0][0], b[1][1] - b[0][1]];
    let la = da[0].hypot(da[1]);
    let lb = db[0].hypot(db[1]);
    if la <= 0.0 || lb <= 0.0 {
        return None;
    }
    let scale = lb / la;
    let rotation = db[1].atan2(db[0]) - da[1].atan2(da[0]);
    let mut s = Similarity {
        scale,
        rotation,
        mirrored,
        translation: [0.0, 0.0],
    };
    let p = s.apply(a[0]);
    s.translation = [b[0][0] - p[0], b[0][1] - p[1]];
    Some(s)
}

/// Each pose's nearest found cross within `tol_px` (each found cross taken once, by its nearest pose), and the
/// number of poses matched and their squared distances.
fn assign(
    s: &Similarity,
    nominal: &[[f64; 2]],
    found: &[[f64; 2]],
    tol_px: f64,
) -> (Vec<Option<usize>>, usize, f64) {
    let mut best: Vec<Option<(usize, f64)>> = vec![None; found.len()];
    for (i, n) in nominal.iter().enumerate() {
        let p = s.apply(*n);
        let nearest = found
            .iter()
            .enumerate()
            .map(|(j, f)| (j, (f[0] - p[0]).powi(2) + (f[1] - p[1]).powi(2)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((j, d2)) = nearest
            && d2 <= tol_px * tol_px
            && best[j].is_none_or(|(_, old)| d2 < old)
        {
            best[j] = Some((i, d2));
        }
    }
    let mut assigned = vec![None; nominal.len()];
    let (mut count, mut sum) = (0, 0.0);
    for (j, b) in best.iter().enumerate() {
        if let Some((i, d2)) = b {
            assigned[*i] = Some(j);
            count += 1;
            sum += d2;
        }
    }
    (assigned, count, sum)
}

/// The least-squares similarity (mirror fixed) of the matched pairs.
fn refit(
    nominal: &[[f64; 2]],
    found: &[[f64; 2]],
    assigned: &[Option<usize>],
    mirrored: bool,
) -> Option<Similarity> {
    let pairs: Vec<([f64; 2], [f64; 2])> = assigned
        .iter()
        .enumerate()
        .filter_map(|(i, j)| {
            j.map(|j| {
                let n = nominal[i];
                (if mirrored { [n[0], -n[1]] } else { n }, found[j])
            })
        })
        .collect();
    if pairs.len() < 2 {
        return None;
    }
    let k = pairs.len() as f64;
    let ma = pairs
        .iter()
        .fold([0.0, 0.0], |m, p| [m[0] + p.0[0] / k, m[1] + p.0[1] / k]);
    let mb = pairs
        .iter()
        .fold([0.0, 0.0], |m, p| [m[0] + p.1[0] / k, m[1] + p.1[1] / k]);
    let (mut sc, mut ss, mut saa) = (0.0, 0.0, 0.0);
    for (a, b) in &pairs {
        let (ax, ay) = (a[0] - ma[0], a[1] - ma[1]);
        let (bx, by) = (b[0] - mb[0], b[1] - mb[1]);
        sc += ax * bx + ay * by;
        ss += ax * by - ay * bx;
        saa += ax * ax + ay * ay;
    }
    if saa <= 0.0 {
        return None;
    }
    let rotation = ss.atan2(sc);
    let scale = sc.hypot(ss) / saa;
    let (s, c) = rotation.sin_cos();
    let rotated = [
        scale * (c * ma[0] - s * ma[1]),
        scale * (s * ma[0] + c * ma[1]),
    ];
    Some(Similarity {
        scale,
        rotation,
        mirrored,
        translation: [mb[0] - rotated[0], mb[1] - rotated[1]],
    })
}

/// Lays the poses' nominal centres (mm) on the found crosses (pixels). `scale` bounds the pixels per mm when
/// known. `None` when no similarity lays even two.
pub fn match_poses(
    nominal: &[[f64; 2]],
    found: &[[f64; 2]],
    scale: Option<(f64, f64)>,
) -> Option<Matching> {
    let tol = tolerance(nominal);
    let (lo, hi) = scale.unwrap_or((1.0, 200.0));
    let mut pairs: Vec<(usize, usize, f64)> = Vec::new();
    for i in 0..nominal.len() {
        for j in i + 1..nominal.len() {
            let d = (nominal[i][0] - nominal[j][0]).hypot(nominal[i][1] - nominal[j][1]);
            pairs.push((i, j, d));
        }
    }
    pairs.sort_by(|a, b| b.2.total_cmp(&a.2));
    pairs.truncate(24);
    let mut best: Option<(usize, f64, Similarity)> = None;
    for &(i, j, d) in &pairs {
        for (a, fa) in found.iter().enumerate() {
            for (b, fb) in found.iter().enumerate() {
                let s = (fa[0] - fb[0]).hypot(fa[1] - fb[1]) / d;
                if a == b || !(lo..=hi).contains(&s) {
                    continue;
                }
                for mirrored in [false, true] {
                    let Some(sim) = through_pair([nominal[i], nominal[j]], [*fa, *fb], mirrored)
                    else {
                        continue;
                    };
                    let (_, count, sum) = assign(&sim, nominal, found, tol * sim.scale);
                    let better = best
                        .as_ref()
                        .is_none_or(|(c, e, _)| count > *c || (count == *c && sum < *e));
                    if better {
                        best = Some((count, sum, sim));
                    }
                }
            }
        }
    }
    let (count, _, mut sim) = best?;
    if count < 2 {
        return None;
    }
    let mut assigned = assign(&sim, nominal, found, tol * sim.scale).0;
    for _ in 0..3 {
        sim = refit(nominal, found, &assigned, sim.mirrored)?;
        assigned = assign(&sim, nominal, found, tol * sim.scale).0;
    }
    let worst_mm = assigned
        .iter()
        .enumerate()
        .filter_map(|(i, j)| {
            j.map(|j| {
                let p = sim.apply(nominal[i]);
                (p[0] - found[j][0]).hypot(p[1] - found[j][1]) / sim.scale
            })
        })
        .fold(0.0, f64::max);
    Some(Matching {
        similarity: sim,
        assigned,
        worst_mm,
    })
}
