//! Sub-pixel refinement: a parabola through the exact scores of the winner's
//! four neighbours at full resolution.

use super::integral::Tables;
use super::pyramid::{Tpl, Win};
use super::search::{eval_positions, Cand, Positions, Sink, Strip};
use super::{FailureCode, MatchStats, Score, MAX_LEVELS};

/// Vertex offset of a parabola through `(−1, m)`, `(0, c)`, `(1, p)`, in [−0.5, 0.5];
/// 0 when the three points are not a strict maximum.
pub(super) fn parabola(m: f64, c: f64, p: f64) -> f64 {
    let den = m - 2.0 * c + p;
    if den >= 0.0 || !den.is_finite() {
        return 0.0;
    }
    (0.5 * (m - p) / den).clamp(-0.5, 0.5)
}

/// The exact scores of the four neighbours (left, right, up, down) of `at`.
struct Probe {
    at: (usize, usize),
    nb: [Option<f64>; 4],
}

impl Sink for Probe {
    fn floor(&self) -> Option<Score> {
        None
    }

    fn offer(&mut self, x: usize, y: usize, s: Score) {
        let d = |p: usize, q: usize| (p as isize).wrapping_sub(q as isize);
        let slot = match (d(x, self.at.0), d(y, self.at.1)) {
            (-1, 0) => self.nb.get_mut(0),
            (1, 0) => self.nb.get_mut(1),
            (0, -1) => self.nb.get_mut(2),
            (0, 1) => self.nb.get_mut(3),
            _ => None,
        };
        if let Some(v) = slot {
            *v = Some(s.to_f64());
        }
    }
}

/// Sub-pixel offsets `(dx, dy)` of the winner `win` (full-resolution position),
/// each in [−0.5, 0.5]; the probe's positions are added to `stats`.
pub(super) fn offsets(
    tpls: &[Option<Tpl>; MAX_LEVELS],
    wins: &[Option<Win>; MAX_LEVELS],
    win: &Cand,
    tables: &mut Tables,
    strip: &mut Strip,
    stats: &mut MatchStats,
) -> Result<(f64, f64), FailureCode> {
    // Sub-pixel: exact scores of the four neighbours at full resolution.
    let (Some(t0), Some(w0)) = (
        tpls.first().copied().flatten(),
        wins.first().copied().flatten(),
    ) else {
        return Err(FailureCode::NccScratchTooSmall);
    };
    let (lx, ly) = w0.last_pos(t0.w, t0.h);
    let bounds = (
        win.x.saturating_sub(1),
        win.y.saturating_sub(1),
        win.x.saturating_add(1).min(lx),
        win.y.saturating_add(1).min(ly),
    );
    let mut probe = Probe {
        at: (win.x, win.y),
        nb: [None; 4],
    };
    let mut sub_stats = MatchStats::default();
    eval_positions(
        &t0,
        (0, &w0),
        Positions::all(bounds),
        tables,
        strip,
        &mut sub_stats,
        &mut probe,
    )?;
    let nb = probe.nb;
    stats.positions_scored = stats
        .positions_scored
        .saturating_add(sub_stats.positions_scored);
    stats.flat_positions = stats
        .flat_positions
        .saturating_add(sub_stats.flat_positions);
    stats.macs = stats.macs.saturating_add(sub_stats.macs);
    let c = win.s.to_f64();
    let offset = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(m), Some(p)) => parabola(m, c, p),
        _ => 0.0,
    };
    let dx = offset(nb[0], nb[1]);
    let dy = offset(nb[2], nb[3]);
    Ok((dx, dy))
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::super::test_util::*;
    use super::super::*;
    use std::vec::Vec;

    /// Verifies: VTSM-NCC-011
    #[test]
    fn sub_pixel_refinement_recovers_fractional_shifts() {
        // A smooth analytic pattern sampled at a fractional offset.
        let pat = |x: f64, y: f64| {
            128.0
                + 60.0 * ((x * 0.21).sin() * (y * 0.17).cos())
                + 40.0 * ((x * 0.07 + y * 0.11).sin())
        };
        let (iw, ih, l) = (100usize, 90usize, 32usize);
        for (sx, sy) in [(0.3f64, -0.2f64), (-0.4, 0.1), (0.0, 0.45)] {
            let (x0, y0) = (37.0 + sx, 29.0 + sy);
            let img: Vec<u8> = (0..iw * ih)
                .map(|i| pat((i % iw) as f64, (i / iw) as f64).round() as u8)
                .collect();
            let t: Vec<u8> = (0..l * l)
                .map(|i| pat((i % l) as f64 + x0, (i / l) as f64 + y0).round() as u8)
                .collect();
            for mode in [Search::Exhaustive, Search::CoarseToFine] {
                let mut b = Bufs::new(l, l, iw, ih, mode);
                let (m, _) = match_template(
                    view(&t, l, l),
                    None,
                    view(&img, iw, ih),
                    Rect::new(0, 0, iw as u32, ih as u32),
                    Filter::Gray,
                    mode,
                    &mut b.scratch(),
                )
                .unwrap();
                assert!(
                    (f64::from(m.sub_x) - x0).abs() < 0.15,
                    "{mode:?} {} vs {x0}",
                    m.sub_x
                );
                assert!(
                    (f64::from(m.sub_y) - y0).abs() < 0.15,
                    "{mode:?} {} vs {y0}",
                    m.sub_y
                );
            }
        }
    }
}
