//! Crystal lattices as initial states (LAMMPS `lattice` + `create_atoms`).

use crate::geometry::Domain;

/// A Bravais lattice with a basis, in the conventional (orthogonal) unit cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LatticeKind {
    /// 3D simple cubic, 1 atom per cell.
    Sc,
    /// 3D body-centred cubic, 2 atoms per cell.
    Bcc,
    /// 3D face-centred cubic, 4 atoms per cell.
    Fcc,
    /// 2D square, 1 atom per cell.
    Sq,
    /// 2D square with a centred atom (LAMMPS `sq2`), 2 atoms per cell.
    Sq2,
    /// 2D hexagonal (triangular) in a `1 x sqrt(3)` cell, 2 atoms per cell.
    Hex,
}

impl LatticeKind {
    /// Every kind with its name in scenario files.
    pub const ALL: [(&'static str, LatticeKind); 6] = [
        ("sc", LatticeKind::Sc),
        ("bcc", LatticeKind::Bcc),
        ("fcc", LatticeKind::Fcc),
        ("sq", LatticeKind::Sq),
        ("sq2", LatticeKind::Sq2),
        ("hex", LatticeKind::Hex),
    ];

    /// The kind named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|&(_, k)| k)
    }

    /// 2 or 3.
    pub fn dimension(self) -> usize {
        match self {
            LatticeKind::Sc | LatticeKind::Bcc | LatticeKind::Fcc => 3,
            LatticeKind::Sq | LatticeKind::Sq2 | LatticeKind::Hex => 2,
        }
    }

    /// Basis atoms in units of the cell sides.
    fn basis(self) -> &'static [[f64; 3]] {
        match self {
            LatticeKind::Sc | LatticeKind::Sq => &[[0.0, 0.0, 0.0]],
            LatticeKind::Bcc | LatticeKind::Sq2 | LatticeKind::Hex => {
                &[[0.0, 0.0, 0.0], [0.5, 0.5, 0.5]]
            }
            LatticeKind::Fcc => &[
                [0.0, 0.0, 0.0],
                [0.5, 0.5, 0.0],
                [0.5, 0.0, 0.5],
                [0.0, 0.5, 0.5],
            ],
        }
    }

    /// Cell sides in units of the lattice constant.
    fn aspect(self) -> [f64; 3] {
        match self {
            LatticeKind::Hex => [1.0, 3f64.sqrt(), 1.0],
            _ => [1.0; 3],
        }
    }
}

/// `cells[d]` unit cells along each axis of `kind` at number density `density`
/// ([`Lattice::new`]): the box and every atom's position, in LAMMPS's
/// `create_atoms` order.
pub fn lattice<const D: usize>(
    kind: LatticeKind,
    density: f64,
    cells: [usize; D],
) -> Result<(Domain<D>, Vec<[f64; D]>), String> {
    let lattice = Lattice::new(kind, density, cells)?;
    Ok((lattice.domain, lattice.points().collect()))
}

/// A filled lattice before its atoms are made: the box, and the positions
/// generated in order when asked ([`Lattice::points`]), so that a rank of a
/// distributed run can keep its own atoms without holding all of them.
#[derive(Clone, Debug, PartialEq)]
pub struct Lattice<const D: usize> {
    /// The periodic box `[0, cells_d a aspect_d)`.
    pub domain: Domain<D>,
    basis: &'static [[f64; 3]],
    side: [f64; D],
    cells: [usize; D],
}

impl<const D: usize> Lattice<D> {
    /// `cells[d]` unit cells along each axis of `kind` at number density
    /// `density` (atoms per unit volume, LAMMPS's reduced density in lj
    /// units): lattice constant `a = (n_basis / (density * prod(aspect)))^(1/D)`,
    /// periodic box `[0, cells_d a aspect_d)`.
    pub fn new(kind: LatticeKind, density: f64, cells: [usize; D]) -> Result<Self, String> {
        if kind.dimension() != D {
            return Err(format!(
                "lattice {kind:?} is {}-dimensional, the system is {D}-dimensional",
                kind.dimension()
            ));
        }
        if !(density.is_finite() && density > 0.0) {
            return Err(format!(
                "lattice density must be finite and > 0, got {density}"
            ));
        }
        if cells.contains(&0) {
            return Err("lattice cells must be >= 1 along every axis".into());
        }
        let basis = kind.basis();
        cells
            .iter()
            .try_fold(basis.len(), |acc, &c| acc.checked_mul(c))
            .filter(|&t| t < u32::MAX as usize)
            .ok_or_else(|| {
                format!(
                    "{cells:?} cells of {} atoms are more than 2^32 - 1 atoms",
                    basis.len()
                )
            })?;
        let aspect = kind.aspect();
        let unit_volume: f64 = aspect[..D].iter().product();
        let a = (basis.len() as f64 / (density * unit_volume)).powf(1.0 / D as f64);
        let side: [f64; D] = std::array::from_fn(|d| a * aspect[d]);
        let length: [f64; D] = std::array::from_fn(|d| cells[d] as f64 * side[d]);
        let domain = Domain::periodic(length).map_err(|e| e.to_string())?;
        Ok(Lattice {
            domain,
            basis,
            side,
            cells,
        })
    }

    /// The number of atoms, `n_basis prod(cells)`.
    pub fn len(&self) -> usize {
        self.basis.len() * self.cells.iter().product::<usize>()
    }

    /// False: a lattice has at least one cell.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The atoms' positions `(cell_d + b_d) side_d` in LAMMPS's `create_atoms`
    /// order (first axis fastest over the cells, the basis fastest of all):
    /// atom `k` of this order has id `k + 1`.
    pub fn points(&self) -> impl Iterator<Item = [f64; D]> + '_ {
        let cells = self.len() / self.basis.len();
        let mut cell = [0usize; D];
        (0..cells).flat_map(move |_| {
            let here = cell;
            // next cell, first axis fastest
            for d in 0..D {
                cell[d] += 1;
                if cell[d] < self.cells[d] {
                    break;
                }
                cell[d] = 0;
            }
            self.basis
                .iter()
                .map(move |b| std::array::from_fn(|d| (here[d] as f64 + b[d]) * self.side[d]))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn density_and_counts_match_the_request() {
        let (dom, pts) = lattice(LatticeKind::Fcc, 0.8442, [5, 5, 5]).unwrap();
        assert_eq!(pts.len(), 500);
        // the box of ../shared/testdata/lammps/lj500.data
        assert!((dom.length[0] - 8.397980956912537).abs() < 1e-13);
        assert!((500.0 / dom.volume() - 0.8442).abs() < 1e-12);
        let (dom, pts) = lattice(LatticeKind::Hex, 0.7, [4, 3]).unwrap();
        assert_eq!(pts.len(), 24);
        assert!((24.0 / dom.volume() - 0.7).abs() < 1e-12);
        // hex: every atom has 6 neighbours at the lattice constant
        let a = dom.length[0] / 4.0;
        for p in &pts {
            let close = pts
                .iter()
                .filter(|q| {
                    let d = dom.separation(p, q);
                    (crate::geometry::norm2(&d).sqrt() - a).abs() < 1e-9
                })
                .count();
            assert_eq!(close, 6);
        }
        let (_, pts) = lattice(LatticeKind::Sq2, 0.8442, [16, 16]).unwrap();
        assert_eq!(pts.len(), 512);
    }

    #[test]
    fn atoms_come_in_create_atoms_order() {
        let (_, pts) = lattice(LatticeKind::Bcc, 2.0, [2, 2, 2]).unwrap();
        // a = 1: cell (0,0,0) basis 0 and 1, then cell (1,0,0)
        assert_eq!(pts[0], [0.0, 0.0, 0.0]);
        assert_eq!(pts[1], [0.5, 0.5, 0.5]);
        assert_eq!(pts[2], [1.0, 0.0, 0.0]);
        assert_eq!(pts[4], [0.0, 1.0, 0.0]);
    }

    #[test]
    fn refuses_bad_requests() {
        assert!(lattice::<2>(LatticeKind::Fcc, 1.0, [2, 2]).is_err());
        assert!(lattice::<3>(LatticeKind::Fcc, -1.0, [2, 2, 2]).is_err());
        assert!(lattice::<3>(LatticeKind::Fcc, 1.0, [2, 0, 2]).is_err());
        assert_eq!(LatticeKind::from_name("hex"), Some(LatticeKind::Hex));
        assert_eq!(LatticeKind::from_name("hcp"), None);
    }
}
