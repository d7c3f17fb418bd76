//! The collision rules of the hard-disk benchmark (SPEC.md sections 2 and 3), in
//! binary64 with exactly the stated association and no fused multiply-add.

use crate::simd::F64x4;

/// The "moving closer" threshold: a pair collides only when `dot < -1e-7`.
pub const APPROACH: f64 = 0.0000001;

/// The box and disc size as the benchmark states them: integer side `L` and radius
/// `r`, entering floating-point expressions as `Lf = (double) L`, `R = (double) r`,
/// and the contact bound `D = (double)((2r)(2r))` computed in integers first.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Table {
    /// Side `L` of the square box `[0, L]^2`.
    pub side: i64,
    /// Radius `r` of every disc.
    pub radius: i64,
}

impl Table {
    /// `Lf`.
    #[inline]
    pub fn side_f(&self) -> f64 {
        self.side as f64
    }

    /// `R`.
    #[inline]
    pub fn radius_f(&self) -> f64 {
        self.radius as f64
    }

    /// `D = (2r)^2`, exact in integers, then converted.
    #[inline]
    pub fn contact(&self) -> f64 {
        ((2 * self.radius) * (2 * self.radius)) as f64
    }

    /// Which walls a disc at `(x, y)` overlaps: `x - R <= 0`, `x + R >= Lf`,
    /// `y - R <= 0`, `y + R >= Lf` (positions are frozen during a resolution, so
    /// this is computed once per step).
    #[inline]
    pub fn walls_at(&self, x: f64, y: f64) -> Walls {
        let (r, l) = (self.radius_f(), self.side_f());
        Walls {
            low_x: x - r <= 0.0,
            high_x: x + r >= l,
            low_y: y - r <= 0.0,
            high_y: y + r >= l,
        }
    }
}

/// The walls one disc overlaps, `W(p)` split by wall.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Walls {
    /// `x - R <= 0`.
    pub low_x: bool,
    /// `x + R >= Lf`.
    pub high_x: bool,
    /// `y - R <= 0`.
    pub low_y: bool,
    /// `y + R >= Lf`.
    pub high_y: bool,
}

impl Walls {
    /// `W(p)`: some wall overlapped.
    #[inline]
    pub fn any(&self) -> bool {
        self.low_x || self.high_x || self.low_y || self.high_y
    }

    /// `WC(p)`: `(x - R <= 0 and vx < 0) or (x + R >= Lf and vx > 0)` or the same in y.
    #[inline]
    pub fn collides(&self, v: &[f64; 2]) -> bool {
        (self.low_x && v[0] < 0.0)
            || (self.high_x && v[0] > 0.0)
            || (self.low_y && v[1] < 0.0)
            || (self.high_y && v[1] > 0.0)
    }

    /// Wall resolution, each axis on its own: `vx <- |vx|` at the low wall, else
    /// `vx <- -|vx|` at the high wall; likewise in y. Apply only when
    /// [`Walls::collides`].
    #[inline]
    pub fn resolve(&self, v: &mut [f64; 2]) {
        for (a, (low, high)) in [(self.low_x, self.high_x), (self.low_y, self.high_y)]
            .into_iter()
            .enumerate()
        {
            if low {
                v[a] = v[a].abs();
            } else if high {
                v[a] = -v[a].abs();
            }
        }
    }
}

/// The frozen geometry of an ordered pair `(a, b)`: `dx = x_b - x_a`,
/// `dy = y_b - y_a` and `q = (dx dx) + (dy dy)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Separation {
    /// `x_b - x_a`.
    pub dx: f64,
    /// `y_b - y_a`.
    pub dy: f64,
    /// `(dx dx) + (dy dy)`.
    pub q: f64,
}

impl Separation {
    /// The separation of `b` from `a`.
    #[inline]
    pub fn between(a: [f64; 2], b: [f64; 2]) -> Self {
        let dx = b[0] - a[0];
        let dy = b[1] - a[1];
        Separation {
            dx,
            dy,
            q: dx * dx + dy * dy,
        }
    }

    /// Pair collision `PC(a, b)` and, when it holds, its resolution: with
    /// `dot = (dvx dx) + (dvy dy)` for `dv = v_b - v_a`, if `dot < -1e-7` then
    /// `s = dot / q`, `v_a += s (dx, dy)`, `v_b -= s (dx, dy)`. The caller has checked
    /// the overlap `q <= D`. Returns whether the velocities changed.
    #[inline]
    pub fn collide(&self, va: &mut [f64; 2], vb: &mut [f64; 2]) -> bool {
        // whole-vector reads and writes (the compiler pairs the lanes), so that the
        // next check of the same disc reads what this one wrote without a stall
        let dv = [vb[0] - va[0], vb[1] - va[1]];
        let dot = dv[0] * self.dx + dv[1] * self.dy;
        if dot < -APPROACH {
            let s = dot / self.q;
            let c = [s * self.dx, s * self.dy];
            *va = [va[0] + c[0], va[1] + c[1]];
            *vb = [vb[0] - c[0], vb[1] - c[1]];
            true
        } else {
            false
        }
    }
}

/// [`Separation::collide`] for four pairs that share no disc, lane `l` holding the
/// pair with separation `(dx_l, dy_l, q_l)` and velocities `va[l]`, `vb[l]`: the
/// same operations in the same order, so the same bits, with a select in place of
/// the branch (`s = dot / q` is computed in every lane and kept only where
/// `dot < -1e-7`). Returns whether some pair collided.
#[inline(always)]
pub(super) fn collide_four(
    [dx, dy, q]: [F64x4; 3],
    va: &mut [[f64; 2]; 4],
    vb: &mut [[f64; 2]; 4],
) -> bool {
    let (vax, vay) = F64x4::unzip_pairs(*va);
    let (vbx, vby) = F64x4::unzip_pairs(*vb);
    let dot = (vbx - vax) * dx + (vby - vay) * dy;
    let limit = F64x4::splat(-APPROACH);
    let s = dot / q;
    let (cx, cy) = (s * dx, s * dy);
    let collided = |new, old| F64x4::select_less(dot, limit, new, old);
    *va = F64x4::zip_pairs(collided(vax + cx, vax), collided(vay + cy, vay));
    *vb = F64x4::zip_pairs(collided(vbx - cx, vbx), collided(vby - cy, vby));
    F64x4::any_less(dot, limit)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_head_on_pair_exchanges_its_velocities() {
        let sep = Separation::between([0.0, 0.0], [2.0, 0.0]);
        let (mut va, mut vb) = ([1.0, 0.0], [-1.0, 0.0]);
        assert!(sep.collide(&mut va, &mut vb));
        assert_eq!((va, vb), ([-1.0, 0.0], [1.0, 0.0]));
        // now separating: no collision
        assert!(!sep.collide(&mut va, &mut vb));
    }

    #[test]
    fn swapping_roles_gives_the_same_bits() {
        let (pa, pb) = ([0.3, 0.7], [1.9, 1.1]);
        let (va0, vb0) = ([0.41, -0.2], [-0.33, 0.05]);
        let (mut va, mut vb) = (va0, vb0);
        Separation::between(pa, pb).collide(&mut va, &mut vb);
        let (mut vb2, mut va2) = (vb0, va0);
        Separation::between(pb, pa).collide(&mut vb2, &mut va2);
        assert_eq!(va.map(f64::to_bits), va2.map(f64::to_bits));
        assert_eq!(vb.map(f64::to_bits), vb2.map(f64::to_bits));
    }

    #[test]
    fn four_lanes_give_the_bits_of_four_single_pairs() {
        let mut rng = crate::random::Rng::new(11);
        let mut value = |scale: f64| (rng.uniform() - 0.5) * scale;
        for round in 0..2000 {
            let mut seps: [Separation; 4] = std::array::from_fn(|l| {
                if round % 7 == 0 && l == 1 {
                    // coincident centres
                    Separation::between([1.0, 1.0], [1.0, 1.0])
                } else {
                    Separation::between([value(4.0), value(4.0)], [value(4.0), value(4.0)])
                }
            });
            let mut va: [[f64; 2]; 4] = std::array::from_fn(|_| [value(2.0), value(2.0)]);
            let mut vb: [[f64; 2]; 4] = std::array::from_fn(|_| [value(2.0), value(2.0)]);
            if round % 5 == 0 {
                // dot = +-0: no collision, and the signed zeros must survive
                va[2] = [-0.0, 0.0];
                vb[2] = [0.0, -0.0];
                // dot = -1e-7 exactly: not moving closer, no collision
                seps[3] = Separation::between([0.0, 0.0], [1.0, 0.0]);
                va[3] = [APPROACH, 0.0];
                vb[3] = [0.0, 0.0];
            }
            let (mut single_a, mut single_b) = (va, vb);
            let mut any = false;
            for l in 0..4 {
                any |= seps[l].collide(&mut single_a[l], &mut single_b[l]);
            }
            let lanes = |f: fn(&Separation) -> f64| F64x4::load(&seps.map(|s| f(&s)));
            let separation = [lanes(|s| s.dx), lanes(|s| s.dy), lanes(|s| s.q)];
            assert_eq!(collide_four(separation, &mut va, &mut vb), any);
            let bits = |v: [[f64; 2]; 4]| v.map(|p| p.map(f64::to_bits));
            assert_eq!(bits(va), bits(single_a), "round {round}");
            assert_eq!(bits(vb), bits(single_b), "round {round}");
        }
    }

    #[test]
    fn coincident_centres_never_collide() {
        let sep = Separation::between([1.0, 1.0], [1.0, 1.0]);
        let (mut va, mut vb) = ([1.0, 0.0], [-1.0, 0.0]);
        assert!(!sep.collide(&mut va, &mut vb));
    }

    #[test]
    fn a_wall_sends_the_disc_away_from_every_wall_it_overlaps() {
        let table = Table {
            side: 10,
            radius: 1,
        };
        let corner = table.walls_at(0.5, 9.5);
        assert!(corner.low_x && corner.high_y && !corner.high_x && !corner.low_y);
        let mut v = [-0.0, 0.5];
        // vx = -0.0 is not < 0, but vy > 0 at the high wall triggers it
        assert!(corner.collides(&v));
        corner.resolve(&mut v);
        assert_eq!(v[0].to_bits(), 0.0f64.to_bits());
        assert_eq!(v, [0.0, -0.5]);
        assert!(!corner.collides(&v));
        assert_eq!(table.contact(), 4.0);
    }
}
