//! Procedural sample depots: the paper's three terrains as a dense heightfield.
//!
//! A [`Terrain`] is built from a [`TerrainKind`], a seed and a cell size. It covers
//! [`GRID_HALF_X_M`] × [`GRID_HALF_Y_M`] around the origin (the 6 m × 12 m depot plus a
//! 1 m margin), world frame x east, y north, z up, metres. Two sample tubes lie at
//! `(0, ±1.5 m)`, 3 m apart. Each cell carries a height, an albedo, a label (sand, rock,
//! tube) and a sky-occlusion factor; rocks are height bumps merged by `max` into a gently
//! undulating base. Outside the grid the ground continues as the plane `z = 0` with a
//! procedural sand albedo, so rays that leave the depot still land on something.
//!
//! * Flagstone: jittered-Voronoi slabs 3–6 cm proud, separated by sand-filled cracks,
//!   dusted with thin sand.
//! * CFA6 and CFA2: rocks drawn from the Golombek & Rapp cumulative fractional area
//!   model `F_k(D) = k·exp(−q(k)·D)`, `q(k) = 1.79 + 0.152/k` (k = 0.06 rocks on sand,
//!   k = 0.02 pebbles on dust and sand). The number of rocks is the model's expected
//!   count over the grid area for diameters in `[D_min, D_max]` (rounded), and each
//!   diameter is drawn by inverse-CDF sampling of the model's size density.
//!
//! Albedo has millimetre detail: per-cell sand grains, multi-octave noise, rock mottling,
//! plus a procedural sub-cell grain term in [`Terrain::albedo`] so close-up renders are
//! not smooth. Generation is deterministic for a seed and does not depend on the thread
//! count (rows are computed independently); rock placement does not depend on the cell
//! size. Memory: about 19 bytes per cell including the max-mip used for ray traversal
//! (≈ 82 MB at 5 mm cells, 21 MB at 10 mm).

use rayon::prelude::*;
use std::f32::consts::PI;
use vtsm_core::rng::Rng;

/// Half-extent of the depot along x (6 m wide), metres.
pub const DEPOT_HALF_X_M: f32 = 3.0;
/// Half-extent of the depot along y (12 m long), metres.
pub const DEPOT_HALF_Y_M: f32 = 6.0;
/// Half-extent of the heightfield along x (depot plus 1 m margin), metres.
pub const GRID_HALF_X_M: f32 = 4.0;
/// Half-extent of the heightfield along y (depot plus 1 m margin), metres.
pub const GRID_HALF_Y_M: f32 = 7.0;
/// Sample tube centres (x, y), metres: 3 m apart on the y axis.
pub const TUBE_XY_M: [[f32; 2]; 2] = [[0.0, -1.5], [0.0, 1.5]];
/// Sample tube radius, metres.
pub const TUBE_RADIUS_M: f32 = 0.02;
/// Sample tube length, metres.
pub const TUBE_LENGTH_M: f32 = 0.16;

/// Cell label: sand, dust or any loose ground.
pub const LABEL_SAND: u8 = 0;
/// Cell label: rock (slab, rock or pebble).
pub const LABEL_ROCK: u8 = 1;
/// Cell label: sample tube.
pub const LABEL_TUBE: u8 = 2;

/// The paper's three terrain types.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TerrainKind {
    /// Broken slabs separated by cracks, thin sand.
    Flagstone,
    /// Rocks on sand, cumulative fractional area k = 6 %.
    Cfa6,
    /// Pebbles on dust and sand, k = 2 %.
    Cfa2,
}

impl TerrainKind {
    /// All kinds, in the paper's order.
    pub const ALL: [TerrainKind; 3] =
        [TerrainKind::Flagstone, TerrainKind::Cfa6, TerrainKind::Cfa2];

    /// Lower-case name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            TerrainKind::Flagstone => "flagstone",
            TerrainKind::Cfa6 => "cfa6",
            TerrainKind::Cfa2 => "cfa2",
        }
    }

    /// Parse a command-line name.
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == s.to_ascii_lowercase())
    }

    /// Whether the sampling mask M̂ keeps only rocks (Flagstone, CFA6) or everything (CFA2).
    pub fn mask_rocks_only(self) -> bool {
        !matches!(self, TerrainKind::Cfa2)
    }

    /// Rock population model, if the terrain has one.
    pub fn cfa(self) -> Option<CfaModel> {
        match self {
            TerrainKind::Flagstone => None,
            TerrainKind::Cfa6 => Some(CfaModel::new(0.06, 0.03, 0.45)),
            TerrainKind::Cfa2 => Some(CfaModel::new(0.02, 0.008, 0.20)),
        }
    }
}

/// Golombek & Rapp (1997) rock abundance: `F_k(D) = k·exp(−q·D)` is the fraction of the
/// surface covered by rocks of diameter ≥ D, truncated to `[d_min_m, d_max_m]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CfaModel {
    /// Total cumulative fractional area k.
    pub k: f32,
    /// `q(k) = 1.79 + 0.152 / k`, per metre.
    pub q: f32,
    /// Smallest diameter placed, metres.
    pub d_min_m: f32,
    /// Largest diameter placed, metres.
    pub d_max_m: f32,
}

impl CfaModel {
    /// The model for abundance `k` truncated to `[d_min_m, d_max_m]`.
    pub fn new(k: f32, d_min_m: f32, d_max_m: f32) -> Self {
        Self {
            k,
            q: 1.79 + 0.152 / k,
            d_min_m,
            d_max_m,
        }
    }

    /// Fraction of area covered by rocks with diameter ≥ `d`.
    pub fn cumulative_area(&self, d: f64) -> f64 {
        f64::from(self.k) * (-f64::from(self.q) * d).exp()
    }

    /// Number of rocks per square metre with diameter in `[d, d + dD]`, per metre of D:
    /// `−F'(D) / (π D² / 4)`.
    pub fn number_density(&self, d: f64) -> f64 {
        let area_density = f64::from(self.k) * f64::from(self.q) * (-f64::from(self.q) * d).exp();
        area_density / (std::f64::consts::PI * d * d * 0.25)
    }

    /// Expected rocks per square metre with diameter in `[lo, hi]` (Simpson's rule on a
    /// log-spaced grid).
    pub fn expected_per_m2(&self, lo: f64, hi: f64) -> f64 {
        if hi <= lo {
            return 0.0;
        }
        // Substitute D = exp(s): integrand n(D)·D ds, smooth in s.
        let (a, b) = (lo.ln(), hi.ln());
        let n = 512;
        let h = (b - a) / n as f64;
        let f = |s: f64| {
            let d = s.exp();
            self.number_density(d) * d
        };
        let mut sum = f(a) + f(b);
        for i in 1..n {
            let w = if i % 2 == 1 { 4.0 } else { 2.0 };
            sum += w * f(a + h * i as f64);
        }
        sum * h / 3.0
    }
}

/// One rock or pebble of a CFA terrain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rock {
    /// Centre x, metres.
    pub x: f32,
    /// Centre y, metres.
    pub y: f32,
    /// Diameter (mean footprint), metres.
    pub diameter_m: f32,
    /// Height above the local ground, metres.
    pub height_m: f32,
    /// Base albedo.
    pub albedo: f32,
    /// Outline harmonics: amplitude and phase of orders 1..=3.
    pub shape: [[f32; 2]; 3],
    /// Orientation of the elongation, radians.
    pub angle: f32,
    /// Elongation ratio (≥ 1).
    pub elongation: f32,
}

/// A procedurally generated depot.
#[derive(Clone, Debug)]
pub struct Terrain {
    /// Terrain type.
    pub kind: TerrainKind,
    /// Seed it was generated from.
    pub seed: u64,
    /// Cell size, metres.
    pub cell_m: f32,
    /// Cells along x.
    pub nx: usize,
    /// Cells along y.
    pub ny: usize,
    /// World x of the centre of cell column 0.
    pub x0: f32,
    /// World y of the centre of cell row 0.
    pub y0: f32,
    /// Rocks placed (CFA terrains; empty for Flagstone).
    pub rocks: Vec<Rock>,
    /// Highest cell, metres.
    pub max_height_m: f32,
    height: Vec<f32>,
    albedo: Vec<f32>,
    label: Vec<u8>,
    sky: Vec<f32>,
    /// Maximum quadtree of the heights, for ray traversal.
    mip: MaxMip,
}

/// Maximum mip-map (min/max quadtree, max half) of the bilinear heightfield, used to skip
/// empty space when tracing rays.
///
/// Level 0 has one node per bilinear patch, the square between four neighbouring cell
/// centres: `(nx − 1) × (ny − 1)` nodes, each the highest of its four corner heights,
/// which bounds the patch since a bilinear patch attains its extremes at the corners.
/// Node `(i, j)` of level `l` covers patches `[i·2^l, (i+1)·2^l) × [j·2^l, (j+1)·2^l)`
/// (clipped to the grid) and holds the maximum of its up to four children; the last
/// level is a single node.
#[derive(Clone, Debug)]
pub struct MaxMip {
    levels: Vec<MipLevel>,
}

#[derive(Clone, Debug)]
struct MipLevel {
    w: usize,
    h: usize,
    max: Vec<f32>,
}

impl MaxMip {
    fn build(height: &[f32], nx: usize, ny: usize) -> Self {
        let (w, h) = (nx.saturating_sub(1).max(1), ny.saturating_sub(1).max(1));
        let at = |i: usize, j: usize| height[j.min(ny - 1) * nx + i.min(nx - 1)];
        let mut max = vec![0.0f32; w * h];
        max.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
            for (i, m) in row.iter_mut().enumerate() {
                *m = at(i, j)
                    .max(at(i + 1, j))
                    .max(at(i, j + 1))
                    .max(at(i + 1, j + 1));
            }
        });
        let mut levels = vec![MipLevel { w, h, max }];
        // Each level halves both sides (rounding up): at most ~64 levels for any size.
        while let Some(prev) = levels.last().filter(|l| l.w > 1 || l.h > 1) {
            let (pw, ph) = (prev.w, prev.h);
            let (w, h) = (pw.div_ceil(2), ph.div_ceil(2));
            let src = &prev.max;
            let mut max = vec![0.0f32; w * h];
            max.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
                let (j0, j1) = (2 * j, (2 * j + 1).min(ph - 1));
                for (i, m) in row.iter_mut().enumerate() {
                    let (i0, i1) = (2 * i, (2 * i + 1).min(pw - 1));
                    *m = src[j0 * pw + i0]
                        .max(src[j0 * pw + i1])
                        .max(src[j1 * pw + i0])
                        .max(src[j1 * pw + i1]);
                }
            });
            levels.push(MipLevel { w, h, max });
        }
        Self { levels }
    }

    /// Number of levels (the last is a single node).
    pub fn num_levels(&self) -> usize {
        self.levels.len()
    }

    /// Nodes along x and y at `level` (`(0, 0)` past the last level).
    pub fn dims(&self, level: usize) -> (usize, usize) {
        self.levels.get(level).map_or((0, 0), |l| (l.w, l.h))
    }

    /// Upper bound of the surface height over node `(i, j)` of `level` (`+∞` for a node
    /// that does not exist, so a caller can never skip terrain by mistake).
    #[inline]
    pub fn node_max(&self, level: usize, i: usize, j: usize) -> f32 {
        match self.levels.get(level) {
            Some(l) if i < l.w && j < l.h => l.max[j * l.w + i],
            _ => f32::INFINITY,
        }
    }
}

// ---------------------------------------------------------------- noise

#[inline]
fn hash3(seed: u64, x: i64, y: i64) -> u64 {
    let mut z = seed
        ^ (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Uniform value in [0, 1) for an integer lattice point.
#[inline]
pub(crate) fn lattice(seed: u64, x: i64, y: i64) -> f32 {
    (hash3(seed, x, y) >> 40) as f32 * (1.0 / 16_777_216.0)
}

/// Smooth value noise in [0, 1) with unit lattice spacing.
#[inline]
pub(crate) fn value_noise(seed: u64, x: f32, y: f32) -> f32 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let (tx, ty) = (x - fx, y - fy);
    let (sx, sy) = (tx * tx * (3.0 - 2.0 * tx), ty * ty * (3.0 - 2.0 * ty));
    let a = lattice(seed, ix, iy);
    let b = lattice(seed, ix + 1, iy);
    let c = lattice(seed, ix, iy + 1);
    let d = lattice(seed, ix + 1, iy + 1);
    let top = a + (b - a) * sx;
    let bot = c + (d - c) * sx;
    top + (bot - top) * sy
}

/// Fractal sum of value noise, result in about [−0.5, 0.5]; `scale_m` is the largest wavelength.
#[inline]
pub(crate) fn fbm(seed: u64, x: f32, y: f32, scale_m: f32, octaves: u32) -> f32 {
    let mut sum = 0.0;
    let mut amp = 0.5;
    let mut freq = 1.0 / scale_m;
    let mut norm = 0.0;
    for o in 0..octaves {
        sum +=
            amp * (value_noise(seed.wrapping_add(u64::from(o) * 7919), x * freq, y * freq) - 0.5);
        norm += amp;
        amp *= 0.5;
        freq *= 2.03;
    }
    sum / norm
}

#[inline]
fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Albedo of loose ground (sand, dust) at a point: used on the grid and beyond it.
fn ground_albedo(kind: TerrainKind, seed: u64, x: f32, y: f32) -> f32 {
    let patches = fbm(seed ^ 0xA1, x, y, 1.2, 4);
    let ripples = fbm(seed ^ 0xA2, x * 0.5 + y * 0.2, y * 1.6, 0.12, 3);
    let base = match kind {
        TerrainKind::Cfa2 => {
            // Bright dust patches over darker sand.
            let dust = smoothstep(-0.05, 0.12, patches);
            0.21 + 0.09 * dust
        }
        _ => 0.23 + 0.10 * patches,
    };
    base + 0.05 * ripples + 0.03 * fbm(seed ^ 0xA3, x, y, 0.02, 2)
}

/// Gentle relief of the base surface, metres.
fn base_height(seed: u64, x: f32, y: f32) -> f32 {
    0.08 * fbm(seed ^ 0xB1, x, y, 3.0, 3) + 0.006 * fbm(seed ^ 0xB2, x, y, 0.15, 3)
}

// ---------------------------------------------------------------- flagstone

const SLAB_SPACING_M: f32 = 0.5;

/// Nearest two jittered-grid sites: (site id, distance to the bisector, site centre).
fn slab_at(seed: u64, x: f32, y: f32) -> (u64, f32, [f32; 2]) {
    let gx = (x / SLAB_SPACING_M).floor() as i64;
    let gy = (y / SLAB_SPACING_M).floor() as i64;
    let mut best = (f32::MAX, 0u64, [0.0f32; 2]);
    let mut second = (f32::MAX, [0.0f32; 2]);
    for dy in -2..=2 {
        for dx in -2..=2 {
            let (cx, cy) = (gx + dx, gy + dy);
            let h = hash3(seed ^ 0x51AB, cx, cy);
            let jx = ((h >> 8) & 0xFFFF) as f32 / 65536.0;
            let jy = ((h >> 24) & 0xFFFF) as f32 / 65536.0;
            let sx = (cx as f32 + 0.1 + 0.8 * jx) * SLAB_SPACING_M;
            let sy = (cy as f32 + 0.1 + 0.8 * jy) * SLAB_SPACING_M;
            let d2 = (x - sx) * (x - sx) + (y - sy) * (y - sy);
            if d2 < best.0 {
                second = (best.0, best.2);
                best = (d2, h, [sx, sy]);
            } else if d2 < second.0 {
                second = (d2, [sx, sy]);
            }
        }
    }
    let sep = ((best.2[0] - second.1[0]).powi(2) + (best.2[1] - second.1[1]).powi(2)).sqrt();
    let edge = (second.0 - best.0) / (2.0 * sep.max(1e-6));
    (best.1, edge, best.2)
}

/// Flagstone: (height above base, albedo, label) at a point.
fn flagstone_cell(seed: u64, x: f32, y: f32, ground: f32) -> (f32, f32, u8) {
    let (id, edge, c) = slab_at(seed, x, y);
    let r = |shift: u32| ((id >> shift) & 0xFF) as f32 / 255.0;
    // About one site in ten is a gap where the slab is broken away.
    if r(0) < 0.08 {
        return (0.0, ground, LABEL_SAND);
    }
    let crack_half = 0.012 + 0.010 * value_noise(seed ^ 0xC4, x * 8.0, y * 8.0);
    let thick = 0.03 + 0.03 * r(8);
    let tilt = [(r(16) - 0.5) * 0.08, (r(24) - 0.5) * 0.08];
    let bevel = smoothstep(crack_half, crack_half + 0.025, edge);
    if bevel <= 0.0 {
        return (0.0, ground, LABEL_SAND);
    }
    let rough = 0.004 * fbm(seed ^ 0xC5, x, y, 0.08, 4);
    let h = (thick + tilt[0] * (x - c[0]) + tilt[1] * (y - c[1]) + rough).max(0.005) * bevel;
    let mottle = fbm(seed ^ 0xC6, x, y, 0.06, 4);
    let rock_albedo = 0.20 + 0.10 * r(32) + 0.10 * mottle;
    // Thin sand dusting, thicker towards the slab edges.
    let sand_cover = smoothstep(
        0.05,
        0.3,
        fbm(seed ^ 0xC7, x, y, 0.25, 4) + 0.25 - 2.0 * edge.min(0.12),
    );
    let a = rock_albedo + (ground - rock_albedo) * sand_cover * 0.8;
    let label = if h > 0.004 { LABEL_ROCK } else { LABEL_SAND };
    (h, a, label)
}

// ---------------------------------------------------------------- rocks

/// Draw the rocks of a CFA terrain over the grid area. Independent of the cell size.
pub fn place_rocks(model: &CfaModel, seed: u64, half_x: f32, half_y: f32) -> Vec<Rock> {
    let area = f64::from(4.0 * half_x * half_y);
    let lo = f64::from(model.d_min_m);
    let hi = f64::from(model.d_max_m);
    let count = (model.expected_per_m2(lo, hi) * area).round() as usize;
    // Inverse CDF of the truncated size density on a log-spaced table.
    let n = 2048usize;
    let mut ds = Vec::with_capacity(n + 1);
    let mut cdf = Vec::with_capacity(n + 1);
    let mut acc = 0.0f64;
    let (la, lb) = (lo.ln(), hi.ln());
    let mut prev = None;
    for i in 0..=n {
        let d = (la + (lb - la) * i as f64 / n as f64).exp();
        let f = model.number_density(d) * d;
        if let Some((pd, pf)) = prev {
            let ds_log = d.ln() - f64::ln(pd);
            acc += 0.5 * (f + pf) * ds_log;
        }
        prev = Some((d, f));
        ds.push(d);
        cdf.push(acc);
    }
    let total = acc.max(1e-300);
    let mut rng = Rng::new(seed).fork(0x0C0C_A000);
    let mut rocks = Vec::with_capacity(count);
    for _ in 0..count {
        let u = f64::from(rng.next_f32()) * total;
        let i = cdf.partition_point(|&c| c < u).clamp(1, n);
        let (c0, c1) = (cdf[i - 1], cdf[i]);
        let t = if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.0 };
        let d = (ds[i - 1].ln() + t * (ds[i].ln() - ds[i - 1].ln())).exp() as f32;
        let x = rng.uniform(-half_x, half_x);
        let y = rng.uniform(-half_y, half_y);
        let height_m = d * rng.uniform(0.28, 0.55);
        let albedo = rng.uniform(0.13, 0.33);
        let mut shape = [[0.0f32; 2]; 3];
        for (o, s) in shape.iter_mut().enumerate() {
            *s = [
                rng.uniform(0.0, 0.18 / (o as f32 + 1.0)),
                rng.uniform(0.0, 2.0 * PI),
            ];
        }
        let angle = rng.uniform(0.0, PI);
        let elongation = rng.uniform(1.0, 1.5);
        rocks.push(Rock {
            x,
            y,
            diameter_m: d,
            height_m,
            albedo,
            shape,
            angle,
            elongation,
        });
    }
    rocks
}

impl Rock {
    /// Outline radius bound (for the bounding box), metres.
    pub fn bound_m(&self) -> f32 {
        0.5 * self.diameter_m * self.elongation.sqrt() * 1.4
    }

    /// Height above ground and albedo at `(x, y)`, or `None` outside the footprint.
    fn sample(&self, seed: u64, idx: usize, x: f32, y: f32) -> Option<(f32, f32)> {
        let (dx, dy) = (x - self.x, y - self.y);
        let (s, c) = self.angle.sin_cos();
        let e = self.elongation.sqrt();
        let (u, v) = ((c * dx + s * dy) / e, (-s * dx + c * dy) * e);
        let r = (u * u + v * v).sqrt();
        let th = v.atan2(u);
        let mut rad = 0.5 * self.diameter_m;
        let mut m = 1.0;
        for (o, sh) in self.shape.iter().enumerate() {
            m += sh[0] * ((o as f32 + 1.0) * th + sh[1]).cos();
        }
        rad *= m;
        let rho = r / rad;
        if rho >= 1.0 {
            return None;
        }
        let rs = seed ^ (idx as u64).wrapping_mul(0x2545_F491_4F6C_DD1D);
        let facets = fbm(rs, x, y, self.diameter_m * 0.5, 3);
        let h =
            self.height_m * ((1.0 - rho * rho).max(0.0).powf(0.55) * (1.0 + 0.25 * facets) - 0.08);
        let mottle = fbm(rs ^ 0x77, x, y, 0.03, 3);
        let a = self.albedo * (1.0 + 0.45 * mottle)
            + 0.04 * (lattice(rs, (x * 400.0) as i64, (y * 400.0) as i64) - 0.5);
        Some((h, a))
    }
}

/// Inclusive cell-index box `[i0, i1] × [j0, j1]`.
type CellBox = [usize; 4];

impl Rock {
    /// Whether the rock reaches within `margin_m` of a sample tube's
    /// footprint (edits of the depot leave those rocks alone).
    fn near_tube(&self, margin_m: f32) -> bool {
        TUBE_XY_M.iter().any(|t| {
            (self.x - t[0]).hypot(self.y - t[1]) < TUBE_LENGTH_M + self.bound_m() + margin_m
        })
    }

    /// Cells that the rock's bounding square touches (clamped to the grid).
    fn cell_box(&self, x0: f32, y0: f32, cell_m: f32, nx: usize, ny: usize) -> CellBox {
        let b = self.bound_m();
        let lo = |c: f32, o: f32| ((c - b - o) / cell_m).floor().max(0.0) as usize;
        let hi = |c: f32, o: f32, n: usize| {
            (((c + b - o) / cell_m).ceil().max(0.0) as usize).min(n.saturating_sub(1))
        };
        [
            lo(self.x, x0),
            hi(self.x, x0, nx),
            lo(self.y, y0),
            hi(self.y, y0, ny),
        ]
    }
}

/// Mutable view of the per-cell layers, for stamping rocks.
struct Cells<'a> {
    nx: usize,
    ny: usize,
    x0: f32,
    y0: f32,
    cell_m: f32,
    height: &'a mut [f32],
    albedo: &'a mut [f32],
    label: &'a mut [u8],
}

impl Cells<'_> {
    /// Stamp rock `idx` (max-combined with what is there) over the cells of `bx`.
    fn stamp_rock(&mut self, tseed: u64, idx: usize, rock: &Rock, bx: CellBox) {
        let ground = base_height(tseed, rock.x, rock.y);
        let [i0, i1, j0, j1] = bx;
        for j in j0..=j1.min(self.ny.saturating_sub(1)) {
            for i in i0..=i1.min(self.nx.saturating_sub(1)) {
                let (x, y) = (
                    self.x0 + i as f32 * self.cell_m,
                    self.y0 + j as f32 * self.cell_m,
                );
                if let Some((dh, a)) = rock.sample(tseed, idx, x, y) {
                    let k = j * self.nx + i;
                    let top = ground + dh;
                    if top > self.height[k] {
                        self.height[k] = top;
                        self.albedo[k] = a;
                        self.label[k] = if top - base_height(tseed, x, y) > 0.002 {
                            LABEL_ROCK
                        } else {
                            LABEL_SAND
                        };
                    }
                }
            }
        }
    }
}

/// Seed of the generator for a terrain kind and user seed.
fn terrain_seed(kind: TerrainKind, seed: u64) -> u64 {
    seed ^ (kind as u64 + 1).wrapping_mul(0x1234_5678_9ABC_DEF1)
}

mod change;

pub use change::{
    DepotChange, BERM_HEIGHT_M, BERM_WIDTH_M, DUST_ALBEDO, GROUSER_ALBEDO, GROUSER_DEPTH_M,
    GROUSER_PITCH_M, MAX_TRACKS, RUT_DEPTH_M, TRACK_ALBEDO, TRACK_GAUGE_M, WHEEL_WIDTH_M,
};

/// Pebbles that wind may move: rocks of at most this diameter, metres.
pub const PEBBLE_MAX_DIAMETER_M: f32 = 0.05;
/// Fraction of the pebbles that wind of strength 1 displaces.
pub const WIND_PEBBLE_FRACTION: f32 = 0.25;

// ---------------------------------------------------------------- terrain

impl Terrain {
    /// Generate a depot of `kind` from `seed` with cells of `cell_m` metres (5 mm for the
    /// paper profile; coarser cells keep tests fast). Deterministic.
    pub fn generate(kind: TerrainKind, seed: u64, cell_m: f32) -> Self {
        let cell_m = cell_m.clamp(0.002, 0.05);
        let nx = (2.0 * GRID_HALF_X_M / cell_m).round() as usize;
        let ny = (2.0 * GRID_HALF_Y_M / cell_m).round() as usize;
        let x0 = -GRID_HALF_X_M + 0.5 * cell_m;
        let y0 = -GRID_HALF_Y_M + 0.5 * cell_m;
        let n = nx * ny;
        let mut height = vec![0.0f32; n];
        let mut albedo = vec![0.0f32; n];
        let mut label = vec![LABEL_SAND; n];
        let tseed = terrain_seed(kind, seed);

        // Base relief, ground albedo with per-cell grains, and Flagstone slabs.
        height
            .par_chunks_mut(nx)
            .zip(albedo.par_chunks_mut(nx))
            .zip(label.par_chunks_mut(nx))
            .enumerate()
            .for_each(|(j, ((hrow, arow), lrow))| {
                let y = y0 + j as f32 * cell_m;
                for (i, ((h, a), l)) in hrow
                    .iter_mut()
                    .zip(arow.iter_mut())
                    .zip(lrow.iter_mut())
                    .enumerate()
                {
                    let x = x0 + i as f32 * cell_m;
                    let grain = 0.05 * (lattice(tseed ^ 0x6A, i as i64, j as i64) - 0.5);
                    let g = ground_albedo(kind, tseed, x, y) + grain;
                    let b = base_height(tseed, x, y);
                    if kind == TerrainKind::Flagstone {
                        let (dh, fa, fl) = flagstone_cell(tseed, x, y, g);
                        *h = b + dh;
                        *a = fa;
                        *l = fl;
                    } else {
                        *h = b;
                        *a = g;
                    }
                }
            });

        // Rocks: stamped sequentially in placement order (max-combined).
        let rocks = kind
            .cfa()
            .map(|m| place_rocks(&m, tseed, GRID_HALF_X_M, GRID_HALF_Y_M))
            .unwrap_or_default();
        let mut cells = Cells {
            nx,
            ny,
            x0,
            y0,
            cell_m,
            height: &mut height,
            albedo: &mut albedo,
            label: &mut label,
        };
        for (idx, rock) in rocks.iter().enumerate() {
            cells.stamp_rock(tseed, idx, rock, rock.cell_box(x0, y0, cell_m, nx, ny));
        }

        // Sample tubes: horizontal cylinders lying on the ground, bright.
        for (t, c) in TUBE_XY_M.iter().enumerate() {
            let ang = 0.6 + 1.3 * t as f32;
            let (s, co) = ang.sin_cos();
            let b = TUBE_LENGTH_M;
            let i0 = ((c[0] - b - x0) / cell_m).floor().max(0.0) as usize;
            let j0 = ((c[1] - b - y0) / cell_m).floor().max(0.0) as usize;
            let i1 = (((c[0] + b - x0) / cell_m).ceil() as usize).min(nx - 1);
            let j1 = (((c[1] + b - y0) / cell_m).ceil() as usize).min(ny - 1);
            // The tube rests on the highest ground under its footprint.
            let mut ground = f32::MIN;
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let (x, y) = (x0 + i as f32 * cell_m, y0 + j as f32 * cell_m);
                    let (dx, dy) = (x - c[0], y - c[1]);
                    if (co * dx + s * dy).abs() <= 0.5 * TUBE_LENGTH_M
                        && (-s * dx + co * dy).abs() < TUBE_RADIUS_M
                    {
                        ground = ground.max(height[j * nx + i]);
                    }
                }
            }
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let (x, y) = (x0 + i as f32 * cell_m, y0 + j as f32 * cell_m);
                    let (dx, dy) = (x - c[0], y - c[1]);
                    let along = co * dx + s * dy;
                    let across = -s * dx + co * dy;
                    if along.abs() <= 0.5 * TUBE_LENGTH_M && across.abs() < TUBE_RADIUS_M {
                        let top = ground
                            + TUBE_RADIUS_M
                            + (TUBE_RADIUS_M * TUBE_RADIUS_M - across * across).sqrt();
                        let k = j * nx + i;
                        if top > height[k] {
                            height[k] = top;
                            albedo[k] = 0.75;
                            label[k] = LABEL_TUBE;
                        }
                    }
                }
            }
        }

        for a in albedo.iter_mut() {
            *a = a.clamp(0.03, 0.95);
        }
        let max_height_m = height.iter().copied().fold(f32::MIN, f32::max);
        let sky = sky_visibility(&height, nx, ny, cell_m);
        let mip = MaxMip::build(&height, nx, ny);
        Self {
            kind,
            seed,
            cell_m,
            nx,
            ny,
            x0,
            y0,
            rocks,
            max_height_m,
            height,
            albedo,
            label,
            sky,
            mip,
        }
    }

    /// A terrain over the standard grid whose cells come from `f(x, y) -> (height,
    /// albedo, label)`: for tests with known geometry (blocks, markers). `kind` decides
    /// the mask rule and the albedo beyond the grid.
    pub fn from_fn(
        kind: TerrainKind,
        seed: u64,
        cell_m: f32,
        f: impl Fn(f32, f32) -> (f32, f32, u8) + Sync,
    ) -> Self {
        let cell_m = cell_m.clamp(0.002, 0.05);
        let nx = (2.0 * GRID_HALF_X_M / cell_m).round() as usize;
        let ny = (2.0 * GRID_HALF_Y_M / cell_m).round() as usize;
        let x0 = -GRID_HALF_X_M + 0.5 * cell_m;
        let y0 = -GRID_HALF_Y_M + 0.5 * cell_m;
        let cells: Vec<(f32, f32, u8)> = (0..nx * ny)
            .into_par_iter()
            .map(|k| f(x0 + (k % nx) as f32 * cell_m, y0 + (k / nx) as f32 * cell_m))
            .collect();
        let height: Vec<f32> = cells.iter().map(|c| c.0).collect();
        let max_height_m = height.iter().copied().fold(f32::MIN, f32::max);
        let sky = sky_visibility(&height, nx, ny, cell_m);
        let mip = MaxMip::build(&height, nx, ny);
        Self {
            kind,
            seed,
            cell_m,
            nx,
            ny,
            x0,
            y0,
            rocks: Vec::new(),
            max_height_m,
            albedo: cells.iter().map(|c| c.1).collect(),
            label: cells.iter().map(|c| c.2).collect(),
            height,
            sky,
            mip,
        }
    }

    /// The same depot with a seeded fraction `frac` (clamped to [0, 1]) of its pebbles
    /// (rocks of diameter ≤ [`PEBBLE_MAX_DIAMETER_M`]) rolled by 1–4 cm in a random
    /// direction (a pebble that would leave the grid stays put). Only the cells under the old and new footprints of the moved pebbles
    /// change: they are regenerated (ground, then every rock touching them in placement
    /// order). Pebbles near a sample tube stay put. Meant for a freshly generated terrain
    /// (regenerated cells lose earlier edits); Flagstone has no pebbles and is returned
    /// unchanged, as is any terrain for `frac` = 0.
    pub fn with_pebbles_displaced(&self, seed: u64, frac: f32) -> Terrain {
        let frac = if frac.is_finite() {
            frac.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut out = self.clone();
        if frac == 0.0 || self.rocks.is_empty() {
            return out;
        }
        let (nx, ny, x0, y0, c) = (self.nx, self.ny, self.x0, self.y0, self.cell_m);
        let mut rng = Rng::new(seed).fork(0x0050_4542_424C);
        let mut boxes: Vec<CellBox> = Vec::new();
        for rock in out.rocks.iter_mut() {
            // One draw per rock whatever happens, so choices do not depend on each other.
            let (pick, dist, ang) = (
                rng.next_f32(),
                rng.uniform(0.01, 0.04),
                rng.uniform(0.0, 2.0 * PI),
            );
            let (x, y) = (rock.x + dist * ang.cos(), rock.y + dist * ang.sin());
            let off_grid = x.abs() >= GRID_HALF_X_M || y.abs() >= GRID_HALF_Y_M;
            if rock.diameter_m > PEBBLE_MAX_DIAMETER_M
                || pick >= frac
                || rock.near_tube(0.05)
                || off_grid
            {
                continue;
            }
            boxes.push(rock.cell_box(x0, y0, c, nx, ny));
            (rock.x, rock.y) = (x, y);
            boxes.push(rock.cell_box(x0, y0, c, nx, ny));
        }
        if boxes.is_empty() {
            return out;
        }
        let keep = vec![true; out.rocks.len()];
        out.regenerate(&boxes, &keep);
        out.refresh_derived();
        out
    }

    /// Regenerate the cells of `boxes` as [`Terrain::generate`] made them:
    /// bare ground, then every rock `idx` with `keep[idx]` that reaches the
    /// box, in placement order (sample tubes and Flagstone slabs are not
    /// redrawn: callers keep edits away from them). Derived layers are left
    /// to [`Terrain::refresh_derived`].
    fn regenerate(&mut self, boxes: &[CellBox], keep: &[bool]) {
        let (nx, ny, x0, y0, c) = (self.nx, self.ny, self.x0, self.y0, self.cell_m);
        let tseed = terrain_seed(self.kind, self.seed);
        let kind = self.kind;
        let rocks = self.rocks.clone();
        let mut cells = Cells {
            nx,
            ny,
            x0,
            y0,
            cell_m: c,
            height: &mut self.height,
            albedo: &mut self.albedo,
            label: &mut self.label,
        };
        for &bx in boxes {
            let [i0, i1, j0, j1] = bx;
            // Bare ground as generated, ...
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let (x, y) = (x0 + i as f32 * c, y0 + j as f32 * c);
                    let grain = 0.05 * (lattice(tseed ^ 0x6A, i as i64, j as i64) - 0.5);
                    let k = j * nx + i;
                    cells.height[k] = base_height(tseed, x, y);
                    cells.albedo[k] = ground_albedo(kind, tseed, x, y) + grain;
                    cells.label[k] = LABEL_SAND;
                }
            }
            // ... then every kept rock that reaches the box, in placement order.
            for (idx, rock) in rocks.iter().enumerate() {
                if !keep.get(idx).copied().unwrap_or(true) {
                    continue;
                }
                let rb = rock.cell_box(x0, y0, c, nx, ny);
                let clip = [rb[0].max(i0), rb[1].min(i1), rb[2].max(j0), rb[3].min(j1)];
                if clip[0] <= clip[1] && clip[2] <= clip[3] {
                    cells.stamp_rock(tseed, idx, rock, clip);
                }
            }
            for j in j0..=j1 {
                for a in cells.albedo[j * nx + i0..=j * nx + i1].iter_mut() {
                    *a = a.clamp(0.03, 0.95);
                }
            }
        }
    }

    /// Recompute what is derived from the heights after an edit: the highest
    /// cell, sky visibility and the maximum quadtree.
    fn refresh_derived(&mut self) {
        self.max_height_m = self.height.iter().copied().fold(f32::MIN, f32::max);
        self.sky = sky_visibility(&self.height, self.nx, self.ny, self.cell_m);
        self.mip = MaxMip::build(&self.height, self.nx, self.ny);
    }

    /// The same depot after "wind" between mapping and relocalization: sand ripples
    /// moved (up to ±4 mm of height on sand cells, scaled by `strength`), dust deposited
    /// in streaks (sand brightened by up to 0.05, rocks blended toward dust by up to
    /// 15 %), and [`WIND_PEBBLE_FRACTION`] × `strength` of the pebbles rolled by 1–4 cm
    /// ([`Terrain::with_pebbles_displaced`]). Other rocks keep their heights and labels.
    /// `strength` is clamped to [0, 1]; 0 returns an identical terrain.
    pub fn with_wind(&self, seed: u64, strength: f32) -> Terrain {
        let k = strength.clamp(0.0, 1.0);
        if k == 0.0 {
            return self.clone();
        }
        let mut out = self.with_pebbles_displaced(seed, WIND_PEBBLE_FRACTION * k);
        let wseed = seed ^ 0x5749_4E44;
        out.edit_cells(|x, y, h, a, l| {
            let streak = smoothstep(-0.1, 0.2, fbm(wseed, x * 0.4 + y, y * 0.3, 0.6, 4));
            match l {
                LABEL_SAND => {
                    *h += k * 0.008 * fbm(wseed ^ 1, x * 0.6 + y * 0.8, y * 1.4 - x * 0.3, 0.08, 3);
                    *a = (*a + k * 0.05 * streak).clamp(0.03, 0.95);
                }
                LABEL_ROCK => *a += (0.30 - *a) * k * 0.15 * streak,
                _ => {}
            }
        });
        out.refresh_derived();
        out
    }

    /// Apply `edit(x, y, height, albedo, label)` to every cell, rows in
    /// parallel (each cell depends only on its own values and position, so
    /// the result does not depend on the thread count). Derived layers are
    /// left to [`Terrain::refresh_derived`].
    fn edit_cells(&mut self, edit: impl Fn(f32, f32, &mut f32, &mut f32, u8) + Sync) {
        let (nx, x0, y0, c) = (self.nx, self.x0, self.y0, self.cell_m);
        self.height
            .par_chunks_mut(nx)
            .zip(self.albedo.par_chunks_mut(nx))
            .zip(self.label.par_chunks(nx))
            .enumerate()
            .for_each(|(j, ((hrow, arow), lrow))| {
                let y = y0 + j as f32 * c;
                for (i, ((h, a), l)) in hrow
                    .iter_mut()
                    .zip(arow.iter_mut())
                    .zip(lrow.iter())
                    .enumerate()
                {
                    edit(x0 + i as f32 * c, y, h, a, *l);
                }
            });
    }

    /// Continuous cell coordinates of a world point.
    #[inline]
    fn grid_coords(&self, x: f32, y: f32) -> (f32, f32) {
        ((x - self.x0) / self.cell_m, (y - self.y0) / self.cell_m)
    }

    /// Whether `(x, y)` lies over the heightfield.
    #[inline]
    pub fn inside(&self, x: f32, y: f32) -> bool {
        x.abs() < GRID_HALF_X_M && y.abs() < GRID_HALF_Y_M
    }

    #[inline]
    fn bilinear(&self, data: &[f32], x: f32, y: f32) -> f32 {
        let (gx, gy) = self.grid_coords(x, y);
        let gx = gx.clamp(0.0, (self.nx - 1) as f32);
        let gy = gy.clamp(0.0, (self.ny - 1) as f32);
        // Non-negative after the clamp, so truncation is the floor (and avoids a libm call).
        let (i, j) = (gx as usize, gy as usize);
        let i1 = (i + 1).min(self.nx - 1);
        let j1 = (j + 1).min(self.ny - 1);
        let (tx, ty) = (gx - i as f32, gy - j as f32);
        let r0 = j * self.nx;
        let r1 = j1 * self.nx;
        let a = data[r0 + i] + (data[r0 + i1] - data[r0 + i]) * tx;
        let b = data[r1 + i] + (data[r1 + i1] - data[r1 + i]) * tx;
        a + (b - a) * ty
    }

    /// Surface height at `(x, y)`, metres (bilinear over cells; 0 outside the grid).
    #[inline]
    pub fn height(&self, x: f32, y: f32) -> f32 {
        if self.inside(x, y) {
            self.bilinear(&self.height, x, y)
        } else {
            0.0
        }
    }

    /// Albedo at `(x, y)` including sub-cell grain detail (about 1.5 mm).
    pub fn albedo(&self, x: f32, y: f32) -> f32 {
        let fine = 0.035 * (value_noise(self.seed ^ 0xF1, x * 650.0, y * 650.0) - 0.5);
        let base = if self.inside(x, y) {
            self.bilinear(&self.albedo, x, y)
        } else {
            ground_albedo(self.kind, self.seed ^ 0xFA, x, y)
        };
        (base * (1.0 + fine * 4.0)).clamp(0.02, 0.98)
    }

    /// Unit surface normal at `(x, y)` from central differences over one cell (one-sided
    /// at the last cell centre; straight up beyond the cell centres, where the ground is
    /// flat).
    pub fn normal(&self, x: f32, y: f32) -> [f32; 3] {
        let e = self.cell_m;
        let (x1, y1) = (
            self.x0 + (self.nx - 1) as f32 * e,
            self.y0 + (self.ny - 1) as f32 * e,
        );
        if !self.inside(x, y) || x < self.x0 || x > x1 || y < self.y0 || y > y1 {
            return [0.0, 0.0, 1.0];
        }
        let dx = central_difference(x, e, self.x0, x1, |u| self.height(u, y));
        let dy = central_difference(y, e, self.y0, y1, |v| self.height(x, v));
        let n = (dx * dx + dy * dy + 1.0).sqrt();
        [-dx / n, -dy / n, 1.0 / n]
    }

    /// Label of the cell nearest `(x, y)`: [`LABEL_SAND`], [`LABEL_ROCK`] or [`LABEL_TUBE`].
    pub fn label(&self, x: f32, y: f32) -> u8 {
        if !self.inside(x, y) {
            return LABEL_SAND;
        }
        let (gx, gy) = self.grid_coords(x, y);
        let i = (gx.round().max(0.0) as usize).min(self.nx - 1);
        let j = (gy.round().max(0.0) as usize).min(self.ny - 1);
        self.label[j * self.nx + i]
    }

    /// Whether `(x, y)` belongs to the sampling mask M̂ (rocks only for Flagstone and
    /// CFA6, everything for CFA2).
    pub fn in_mask(&self, x: f32, y: f32) -> bool {
        !self.kind.mask_rocks_only() || self.label(x, y) == LABEL_ROCK
    }

    /// Fraction of the sky hemisphere not hidden by nearby relief (1 on open ground,
    /// lower in cracks and at rock feet).
    pub fn sky_visibility(&self, x: f32, y: f32) -> f32 {
        if self.inside(x, y) {
            self.bilinear(&self.sky, x, y)
        } else {
            1.0
        }
    }

    /// Cell-centre heights, row-major (`nx` per row), metres.
    pub fn height_grid(&self) -> &[f32] {
        &self.height
    }

    /// The maximum quadtree of the heights (for ray traversal).
    pub fn max_mip(&self) -> &MaxMip {
        &self.mip
    }

    /// Heights of the four corners of bilinear patch `(i, j)` (between cell centres
    /// `i..=i+1` along x and `j..=j+1` along y): `[h(i,j), h(i+1,j), h(i,j+1), h(i+1,j+1)]`.
    /// Indices are clamped to the grid.
    #[inline]
    pub fn patch(&self, i: usize, j: usize) -> [f32; 4] {
        let (i0, j0) = (i.min(self.nx - 1), j.min(self.ny - 1));
        let (i1, j1) = ((i0 + 1).min(self.nx - 1), (j0 + 1).min(self.ny - 1));
        let h = &self.height;
        [
            h[j0 * self.nx + i0],
            h[j0 * self.nx + i1],
            h[j1 * self.nx + i0],
            h[j1 * self.nx + i1],
        ]
    }

    /// Centre of tube `t` (0 or 1) on the surface, metres.
    pub fn tube_centre(&self, t: usize) -> [f32; 3] {
        let c = TUBE_XY_M[t.min(1)];
        [c[0], c[1], self.height(c[0], c[1])]
    }

    /// Fraction of grid cells labelled rock.
    pub fn rock_fraction(&self) -> f32 {
        self.label.iter().filter(|&&l| l == LABEL_ROCK).count() as f32 / self.label.len() as f32
    }
}

/// Derivative of `f` at `a` by central differences over `±e`, one-sided where `a ± e`
/// would leave `[lo, hi]`.
#[inline]
fn central_difference(a: f32, e: f32, lo: f32, hi: f32, f: impl Fn(f32) -> f32) -> f32 {
    if a - e >= lo && a + e <= hi {
        (f(a + e) - f(a - e)) / (2.0 * e)
    } else {
        let (p, m) = ((a + e).min(hi), (a - e).max(lo));
        (f(p) - f(m)) / (p - m).max(1e-9)
    }
}

/// Sky visibility from a cavity measure: how far a cell sits below the mean of its
/// surroundings (about 4 cm), mapped to [0.35, 1].
fn sky_visibility(height: &[f32], nx: usize, ny: usize, cell_m: f32) -> Vec<f32> {
    let r = ((0.04 / cell_m).round() as usize).max(1);
    let blur = box_blur(height, nx, ny, r);
    height
        .iter()
        .zip(blur.iter())
        .map(|(h, b)| (1.0 - 9.0 * (b - h).max(0.0)).clamp(0.35, 1.0))
        .collect()
}

fn box_blur(data: &[f32], nx: usize, ny: usize, r: usize) -> Vec<f32> {
    let mut tmp = vec![0.0f32; data.len()];
    tmp.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
        let src = &data[j * nx..(j + 1) * nx];
        for (i, o) in row.iter_mut().enumerate() {
            let (a, b) = (i.saturating_sub(r), (i + r).min(nx - 1));
            *o = src[a..=b].iter().sum::<f32>() / (b - a + 1) as f32;
        }
    });
    let mut out = vec![0.0f32; data.len()];
    out.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
        let (a, b) = (j.saturating_sub(r), (j + r).min(ny - 1));
        for jj in a..=b {
            for (o, v) in row.iter_mut().zip(tmp[jj * nx..(jj + 1) * nx].iter()) {
                *o += v;
            }
        }
        let inv = 1.0 / (b - a + 1) as f32;
        row.iter_mut().for_each(|o| *o *= inv);
    });
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;

    /// Verifies: VTSM-SIM-002
    #[test]
    fn cfa_rock_counts_follow_the_golombek_rapp_model() {
        for kind in [TerrainKind::Cfa6, TerrainKind::Cfa2] {
            let m = kind.cfa().unwrap();
            let rocks = place_rocks(&m, 42, GRID_HALF_X_M, GRID_HALF_Y_M);
            let area = f64::from(4.0 * GRID_HALF_X_M * GRID_HALF_Y_M);
            // Independent reference: cumulative number N(≥D) by midpoint integration of
            // −F'(D)/(πD²/4) on a linear grid.
            let reference = |d0: f64| {
                let (a, b) = (d0, f64::from(m.d_max_m));
                let n = 200_000;
                let h = (b - a) / n as f64;
                let k = f64::from(m.k);
                let q = 1.79 + 0.152 / k;
                (0..n)
                    .map(|i| {
                        let d = a + (i as f64 + 0.5) * h;
                        k * q * (-q * d).exp() / (std::f64::consts::PI * d * d / 4.0) * h
                    })
                    .sum::<f64>()
                    * area
            };
            for frac in [0.0f64, 0.1, 0.25, 0.5] {
                let d0 = f64::from(m.d_min_m) + frac * f64::from(m.d_max_m - m.d_min_m);
                let expected = reference(d0);
                let got = rocks
                    .iter()
                    .filter(|r| f64::from(r.diameter_m) >= d0)
                    .count() as f64;
                let tol = (4.0 * expected.sqrt()).max(3.0);
                assert!(
                    (got - expected).abs() <= tol,
                    "{kind:?} N(D>={d0:.3}) = {got}, model {expected:.1} ± {tol:.1}"
                );
            }
            // Covered area fraction against k·(e^{−q Dmin} − e^{−q Dmax}).
            let covered: f64 = rocks
                .iter()
                .map(|r| std::f64::consts::PI * f64::from(r.diameter_m).powi(2) / 4.0)
                .sum::<f64>()
                / area;
            let model =
                m.cumulative_area(f64::from(m.d_min_m)) - m.cumulative_area(f64::from(m.d_max_m));
            assert!(
                (covered - model).abs() < 0.15 * model,
                "{kind:?} covered {covered:.4} vs model {model:.4}"
            );
        }
    }

    /// Verifies: VTSM-SIM-001
    #[test]
    fn terrains_have_rocks_relief_and_textured_albedo() {
        for kind in TerrainKind::ALL {
            let t = Terrain::generate(kind, 7, 0.02);
            let rf = t.rock_fraction();
            match kind {
                TerrainKind::Flagstone => {
                    assert!(rf > 0.5 && rf < 0.9, "flagstone rock fraction {rf}")
                }
                TerrainKind::Cfa6 => assert!(rf > 0.03 && rf < 0.12, "cfa6 rock fraction {rf}"),
                TerrainKind::Cfa2 => assert!(rf > 0.005 && rf < 0.05, "cfa2 rock fraction {rf}"),
            }
            // Albedo is not flat: within a 10 cm patch of sand the values vary.
            let mut v = Vec::new();
            for j in 0..50 {
                for i in 0..50 {
                    v.push(t.albedo(0.7 + i as f32 * 0.002, -0.4 + j as f32 * 0.002));
                }
            }
            let mean = v.iter().sum::<f32>() / v.len() as f32;
            let sd = (v.iter().map(|a| (a - mean).powi(2)).sum::<f32>() / v.len() as f32).sqrt();
            assert!(sd > 0.01, "{kind:?} albedo sd {sd}");
            assert!(mean > 0.1 && mean < 0.45);
            // Tubes stand proud of the ground and are labelled.
            let c = t.tube_centre(1);
            assert_eq!(t.label(c[0], c[1]), LABEL_TUBE);
            assert!(t.max_height_m > 0.03);
        }
    }

    /// The max-mip node over `(x, y)` at every level bounds the surface height there.
    fn assert_mip_bounds(t: &Terrain, x: f32, y: f32) {
        let (gx, gy) = t.grid_coords(x, y);
        let i = (gx.max(0.0) as usize).min(t.nx - 2);
        let j = (gy.max(0.0) as usize).min(t.ny - 2);
        let h = t.height(x, y);
        let mip = t.max_mip();
        for lvl in 0..mip.num_levels() {
            let bound = mip.node_max(lvl, i >> lvl, j >> lvl);
            assert!(h <= bound + 1e-6, "level {lvl}: {h} > {bound}");
        }
        assert_eq!(mip.dims(mip.num_levels() - 1), (1, 1));
        assert!((mip.node_max(mip.num_levels() - 1, 0, 0) - t.max_height_m).abs() < 1e-6);
    }

    /// Verifies: VTSM-SIM-005
    #[test]
    fn max_mip_bounds_hold_everywhere() {
        let t = Terrain::generate(TerrainKind::Cfa6, 3, 0.02);
        let mip = t.max_mip();
        assert_eq!(mip.dims(0), (t.nx - 1, t.ny - 1));
        assert_eq!(mip.node_max(0, t.nx, 0), f32::INFINITY);
        let mut rng = Rng::new(9);
        for _ in 0..4000 {
            assert_mip_bounds(&t, rng.uniform(-3.99, 3.99), rng.uniform(-6.99, 6.99));
        }
        // Each node is exactly the maximum of its children.
        for lvl in 1..mip.num_levels() {
            let (w, h) = mip.dims(lvl);
            let (cw, ch) = mip.dims(lvl - 1);
            for j in 0..h {
                for i in 0..w {
                    let mut m = f32::MIN;
                    for (a, b) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        if 2 * i + a < cw && 2 * j + b < ch {
                            m = m.max(mip.node_max(lvl - 1, 2 * i + a, 2 * j + b));
                        }
                    }
                    assert_eq!(mip.node_max(lvl, i, j), m);
                }
            }
        }
    }

    /// Verifies: VTSM-SIM-012
    #[test]
    fn wind_changes_sand_but_not_rocks() {
        let t = Terrain::generate(TerrainKind::Cfa6, 8, 0.04);
        assert_eq!(t.with_wind(3, 0.0).height, t.height);
        let w = t.with_wind(3, 1.0);
        // Wind rolls some pebbles first; sand and dust are compared against that.
        let t = t.with_pebbles_displaced(3, WIND_PEBBLE_FRACTION);
        assert_eq!(w.rocks, t.rocks);
        let (mut sand_dh, mut sand_da, mut n_sand) = (0.0f32, 0.0f32, 0usize);
        for k in 0..t.height.len() {
            match t.label[k] {
                LABEL_SAND => {
                    sand_dh = sand_dh.max((w.height[k] - t.height[k]).abs());
                    sand_da += (w.albedo[k] - t.albedo[k]).abs();
                    n_sand += 1;
                }
                _ => assert_eq!(w.height[k], t.height[k]),
            }
        }
        assert_eq!(w.label, t.label);
        assert!(
            sand_dh > 0.001 && sand_dh <= 0.0041,
            "sand moved by {sand_dh}"
        );
        let mean_da = sand_da / n_sand as f32;
        assert!(mean_da > 0.005 && mean_da <= 0.05, "dust {mean_da}");
        // The max-mip bounds still hold after the change.
        let mut rng = Rng::new(2);
        for _ in 0..500 {
            assert_mip_bounds(&w, rng.uniform(-3.5, 3.5), rng.uniform(-6.5, 6.5));
        }
    }

    /// Verifies: VTSM-SIM-012
    #[test]
    fn wind_displaces_some_pebbles_and_nothing_far_from_them() {
        let t = Terrain::generate(TerrainKind::Cfa2, 8, 0.01);
        assert_eq!(t.with_pebbles_displaced(4, 0.0).height, t.height);
        let d = t.with_pebbles_displaced(4, 0.3);
        assert_eq!(d.rocks.len(), t.rocks.len());
        let moved: Vec<(Rock, Rock)> = t
            .rocks
            .iter()
            .zip(d.rocks.iter())
            .filter(|(a, b)| a != b)
            .map(|(a, b)| (*a, *b))
            .collect();
        let pebbles = t
            .rocks
            .iter()
            .filter(|r| r.diameter_m <= PEBBLE_MAX_DIAMETER_M)
            .count();
        let share = moved.len() as f32 / pebbles as f32;
        assert!(
            pebbles > 100 && share > 0.2 && share < 0.4,
            "{} of {pebbles} moved",
            moved.len()
        );
        for (a, b) in &moved {
            let dist = (a.x - b.x).hypot(a.y - b.y);
            assert!(a.diameter_m <= PEBBLE_MAX_DIAMETER_M);
            assert!((0.0099..=0.0401).contains(&dist), "moved {dist}");
            assert_eq!((a.diameter_m, a.height_m), (b.diameter_m, b.height_m));
        }
        // Cells change only within reach of a moved pebble's old or new footprint.
        let near = |x: f32, y: f32| {
            moved.iter().any(|(a, b)| {
                let r = a.bound_m() + 2.0 * t.cell_m;
                (x - a.x).abs() <= r && (y - a.y).abs() <= r
                    || (x - b.x).abs() <= r && (y - b.y).abs() <= r
            })
        };
        let mut changed = vec![false; moved.len()];
        let mut n_changed = 0usize;
        for j in 0..t.ny {
            for i in 0..t.nx {
                let k = j * t.nx + i;
                let (x, y) = (t.x0 + i as f32 * t.cell_m, t.y0 + j as f32 * t.cell_m);
                let same = d.height[k] == t.height[k]
                    && d.albedo[k] == t.albedo[k]
                    && d.label[k] == t.label[k];
                if same {
                    continue;
                }
                n_changed += 1;
                assert!(near(x, y), "cell ({x}, {y}) changed far from moved pebbles");
                for (m, (a, b)) in moved.iter().enumerate() {
                    let r = a.bound_m();
                    if (x - a.x).hypot(y - a.y) <= r || (x - b.x).hypot(y - b.y) <= r {
                        changed[m] = true;
                    }
                }
            }
        }
        // Where pebbles moved, the heightfield did change (a pebble hidden under a
        // larger rock may leave it as it was).
        let seen = changed.iter().filter(|&&c| c).count();
        assert!(
            seen as f32 >= 0.8 * moved.len() as f32,
            "{seen} of {} moved pebbles changed the heightfield",
            moved.len()
        );
        assert!(n_changed > 0);
        // Deterministic, and the mip still bounds the new surface.
        assert_eq!(t.with_pebbles_displaced(4, 0.3).height, d.height);
        let mut rng = Rng::new(5);
        for _ in 0..500 {
            assert_mip_bounds(&d, rng.uniform(-3.9, 3.9), rng.uniform(-6.9, 6.9));
        }
        // Flagstone has no pebbles.
        let f = Terrain::generate(TerrainKind::Flagstone, 8, 0.04);
        assert_eq!(f.with_pebbles_displaced(4, 1.0).height, f.height);
    }

    #[test]
    fn generation_is_deterministic() {
        let a = Terrain::generate(TerrainKind::Flagstone, 5, 0.04);
        let b = Terrain::generate(TerrainKind::Flagstone, 5, 0.04);
        assert_eq!(a.height, b.height);
        assert_eq!(a.albedo, b.albedo);
        let c = Terrain::generate(TerrainKind::Flagstone, 6, 0.04);
        assert_ne!(a.height, c.height);
    }
}
