//! When a Verlet list is rebuilt: LAMMPS's `neigh_modify every N check yes|no`
//! (GROMACS's `nstlist`).

/// The list is looked at every `every` steps since its last build, and rebuilt
/// then if `check` is off or some particle has moved more than `skin / 2` since
/// that build: step `s` after the build rebuilds when
/// `s mod every = 0  and  (not check  or  max_i |x_i - x_i^build| > skin / 2)`.
/// The default, every 1 with the check, rebuilds exactly when the skin test
/// says so.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RebuildRule {
    /// Steps between two looks at the list (at least 1).
    pub every: u64,
    /// Rebuild only when some particle moved more than `skin / 2`.
    pub check: bool,
}

impl Default for RebuildRule {
    fn default() -> Self {
        RebuildRule {
            every: 1,
            check: true,
        }
    }
}

/// What [`RebuildRule::decide`] says about one step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rebuild {
    /// Keep the list.
    No,
    /// Rebuild it; `late` when some particle had moved more than `skin / 2`
    /// and the list was not looked at on every step, so that pairs may have
    /// been missed since the last look (LAMMPS's "dangerous builds").
    Yes {
        /// Some particle had moved more than `skin / 2` by now.
        late: bool,
    },
}

impl RebuildRule {
    /// The decision `since` steps after the last build; `moved` runs the skin
    /// test (`max_i |x_i - x_i^build| > skin / 2`), only on the steps the list
    /// is looked at.
    pub fn decide(&self, since: u64, moved: impl FnOnce() -> bool) -> Rebuild {
        if !since.is_multiple_of(self.every.max(1)) {
            return Rebuild::No;
        }
        let moved = moved();
        if moved || !self.check {
            Rebuild::Yes {
                late: moved && self.every > 1,
            }
        } else {
            Rebuild::No
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The steps after a build on which `rule` rebuilds, over `steps` steps,
    /// the skin test answering `moved_at(since)`.
    fn rebuild_steps(rule: RebuildRule, steps: u64, moved_at: impl Fn(u64) -> bool) -> Vec<u64> {
        let mut since = 0;
        let mut built = Vec::new();
        for step in 1..=steps {
            since += 1;
            if let Rebuild::Yes { .. } = rule.decide(since, || moved_at(since)) {
                built.push(step);
                since = 0;
            }
        }
        built
    }

    #[test]
    fn every_one_with_check_follows_the_skin_test() {
        let rule = RebuildRule::default();
        assert_eq!(rebuild_steps(rule, 10, |since| since == 3), vec![3, 6, 9]);
        assert_eq!(rebuild_steps(rule, 5, |_| false), Vec::<u64>::new());
    }

    #[test]
    fn without_check_rebuilds_every_n_steps() {
        let rule = RebuildRule {
            every: 4,
            check: false,
        };
        assert_eq!(rebuild_steps(rule, 13, |_| false), vec![4, 8, 12]);
    }

    #[test]
    fn with_check_looks_only_every_n_steps() {
        let rule = RebuildRule {
            every: 2,
            check: true,
        };
        // the test would fire from the third step after a build on; it is
        // looked at on the fourth
        assert_eq!(rebuild_steps(rule, 9, |since| since >= 3), vec![4, 8]);
    }

    #[test]
    fn a_build_after_the_skin_was_crossed_is_late_unless_every_step_is_checked() {
        let moved = || true;
        let every_step = RebuildRule::default();
        assert_eq!(every_step.decide(1, moved), Rebuild::Yes { late: false });
        let sparse = RebuildRule {
            every: 20,
            check: false,
        };
        assert_eq!(sparse.decide(20, moved), Rebuild::Yes { late: true });
        assert_eq!(sparse.decide(20, || false), Rebuild::Yes { late: false });
        assert_eq!(sparse.decide(19, || panic!("not looked at")), Rebuild::No);
    }
}
