//! The scene two of the components' tests share: scattered discs grouped as a
//! step groups them.

use super::resolve::Components;
use crate::models::billiards::contacts::{Contact, ContactGrid};
use crate::models::billiards::rules::Walls;
use crate::random::Rng;
use crate::threads::Threads;

/// What [`Components::group`] is given, and the pairs by vector position.
pub(super) struct Scene {
    pub(super) n: usize,
    /// The pairs by vector position, in canonical order ([`ContactGrid::find`]).
    pub(super) contacts: Vec<Contact>,
    /// The same pairs as the search found them (slots).
    pub(super) found: Vec<Vec<Contact>>,
    /// The discs on a wall, by slot, ascending.
    pub(super) walls: Vec<(u32, Walls)>,
    /// Each slot's disc.
    pub(super) number: Vec<u32>,
}

impl Scene {
    /// Each disc's slot.
    pub(super) fn slot_of(&self) -> Vec<u32> {
        let mut slot_of = vec![0; self.n];
        for (k, &d) in self.number.iter().enumerate() {
            slot_of[d as usize] = k as u32;
        }
        slot_of
    }

    pub(super) fn group(&self, threads: usize) -> Components {
        let mut components = Components::default();
        let pool = Threads::new(threads).unwrap();
        components.group(&self.found, &self.walls, &self.number, &pool);
        components
    }
}

/// 2000 discs at random in a 60 x 60 square, in contact within `q <= limit`,
/// the last five far from everything; every 97th disc and the far ones on a
/// wall, so that some components are walls only.
pub(super) fn scattered_discs(limit: f64) -> Scene {
    let mut rng = Rng::new(5);
    let n = 2000;
    let mut x: Vec<f64> = (0..n).map(|_| rng.uniform() * 60.0).collect();
    let mut y: Vec<f64> = (0..n).map(|_| rng.uniform() * 60.0).collect();
    // the last few far from everything
    for k in n - 5..n {
        (x[k], y[k]) = (500.0 + 10.0 * k as f64, 500.0);
    }
    let mut contacts = Vec::new();
    // (the cells over the square alone: the search's rows then split its
    // pairs into parts of the slots, with pairs across them)
    let mut grid = ContactGrid::default().with_region([0.0; 2], [60.0; 2]);
    grid.find(&x, &y, limit, &Threads::single(), &mut contacts);
    // some discs on a wall, some of them without a pair: components of walls only
    let wall = Walls {
        low_x: true,
        ..Walls::default()
    };
    let number = grid.nearby_order().to_vec();
    let walls: Vec<(u32, Walls)> = (0..n as u32)
        .filter(|&k| number[k as usize] % 97 == 0 || number[k as usize] as usize >= n - 5)
        .map(|k| (k, wall))
        .collect();
    Scene {
        n,
        contacts,
        found: grid.found().to_vec(),
        walls,
        number,
    }
}
