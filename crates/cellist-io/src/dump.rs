//! Trajectory frames: LAMMPS text dumps (`dump custom`) and extended XYZ.

use crate::output::format_g17;
use std::io::{self, Write};

/// The per-atom columns a LAMMPS dump may hold.
pub const DUMP_COLUMNS: [&str; 12] = [
    "id", "type", "x", "y", "z", "vx", "vy", "vz", "fx", "fy", "fz", "pe",
];

/// The per-body columns a gravity dump may hold.
pub const GRAVITY_DUMP_COLUMNS: [&str; 12] = [
    "id", "mass", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az", "phi",
];

/// One frame's data, atoms already in the order to write (sorted by id).
pub struct Frame<'a> {
    /// Timestep number.
    pub step: u64,
    /// Box lower corner (x, y, z; a 2D box gets z from -0.5 to 0.5).
    pub lo: [f64; 3],
    /// Box upper corner.
    pub hi: [f64; 3],
    /// Periodic per axis.
    pub periodic: [bool; 3],
    /// Atom ids.
    pub ids: &'a [u64],
    /// Atom types.
    pub types: &'a [u32],
    /// Positions (z = 0 in 2D).
    pub positions: &'a [[f64; 3]],
    /// Velocities.
    pub velocities: &'a [[f64; 3]],
    /// Forces.
    pub forces: &'a [[f64; 3]],
    /// Per-atom potential energy, when a column asks for it.
    pub energies: Option<&'a [f64]>,
    /// Masses, for a `mass` column.
    pub masses: Option<&'a [f64]>,
    /// Accelerations, for `ax ay az` columns.
    pub accelerations: Option<&'a [[f64; 3]]>,
    /// Potentials `phi` (energy per unit mass), for a `phi` column.
    pub potentials: Option<&'a [f64]>,
}

/// C's `%-1.16e` (LAMMPS's box-bound format): `d.dddddddddddddddde+XX`; `inf`,
/// `-inf` and `nan` as C prints them.
pub fn format_e16(x: f64) -> String {
    if !x.is_finite() {
        return if x.is_nan() {
            "nan".into()
        } else if x > 0.0 {
            "inf".into()
        } else {
            "-inf".into()
        };
    }
    let s = format!("{x:.16e}");
    let (mantissa, exponent) = s.split_once('e').expect("exponent form");
    let exponent: i32 = exponent.parse().expect("integer exponent");
    let sign = if exponent < 0 { '-' } else { '+' };
    format!("{mantissa}e{sign}{:02}", exponent.abs())
}

/// Writes the head of a LAMMPS text dump frame of `count` atoms: the step and
/// box of `frame`, the count and the `ITEM: ATOMS` line of `columns`. The atom
/// lines follow, from one frame or several blocks of one
/// ([`write_lammps_rows`]).
pub fn write_lammps_head<W: Write + ?Sized>(
    out: &mut W,
    frame: &Frame,
    count: usize,
    columns: &[String],
) -> io::Result<()> {
    writeln!(
        out,
        "ITEM: TIMESTEP\n{}\nITEM: NUMBER OF ATOMS\n{count}",
        frame.step,
    )?;
    let flags: Vec<&str> = frame
        .periodic
        .iter()
        .map(|&p| if p { "pp" } else { "ff" })
        .collect();
    writeln!(out, "ITEM: BOX BOUNDS {}", flags.join(" "))?;
    for a in 0..3 {
        writeln!(
            out,
            "{} {}",
            format_e16(frame.lo[a]),
            format_e16(frame.hi[a])
        )?;
    }
    writeln!(out, "ITEM: ATOMS {}", columns.join(" "))
}

/// Writes one line per atom of `frame` with the given `columns` (names from
/// [`DUMP_COLUMNS`]), numbers at `%.17g`.
pub fn write_lammps_rows<W: Write + ?Sized>(
    out: &mut W,
    frame: &Frame,
    columns: &[String],
) -> io::Result<()> {
    let mut line = String::new();
    for k in 0..frame.ids.len() {
        line.clear();
        for (c, name) in columns.iter().enumerate() {
            if c > 0 {
                line.push(' ');
            }
            match name.as_str() {
                "id" => line.push_str(&frame.ids[k].to_string()),
                "type" => line.push_str(&frame.types[k].to_string()),
                "x" | "y" | "z" => format_g17(frame.positions[k][axis(name)], &mut line),
                "vx" | "vy" | "vz" => format_g17(frame.velocities[k][axis(name)], &mut line),
                "fx" | "fy" | "fz" => format_g17(frame.forces[k][axis(name)], &mut line),
                "pe" => format_g17(
                    frame.energies.expect("energies computed for a pe column")[k],
                    &mut line,
                ),
                "mass" => format_g17(
                    frame.masses.expect("masses for a mass column")[k],
                    &mut line,
                ),
                "ax" | "ay" | "az" => format_g17(
                    frame.accelerations.expect("accelerations for a column")[k][axis(name)],
                    &mut line,
                ),
                "phi" => format_g17(
                    frame.potentials.expect("potentials for a phi column")[k],
                    &mut line,
                ),
                other => panic!("unknown dump column {other}"),
            }
        }
        line.push('\n');
        out.write_all(line.as_bytes())?;
    }
    Ok(())
}

fn axis(name: &str) -> usize {
    match name.as_bytes()[name.len() - 1] {
        b'x' => 0,
        b'y' => 1,
        _ => 2,
    }
}

/// Writes the two head lines of an extended XYZ frame (ASE, OVITO) of `count`
/// particles at `time`, with the step and box of `frame`: `Lattice`, `Origin`,
/// `pbc`, `Time`, `Step` and the columns species (`X`), id, type, pos, velo,
/// forces. The particle lines follow, from
/// one frame or several blocks of one ([`write_xyz_rows`]).
pub fn write_xyz_head<W: Write + ?Sized>(
    out: &mut W,
    frame: &Frame,
    count: usize,
    time: f64,
) -> io::Result<()> {
    let l: Vec<f64> = (0..3).map(|a| frame.hi[a] - frame.lo[a]).collect();
    let mut header = String::new();
    let num = |x: f64, s: &mut String| format_g17(x, s);
    header.push_str("Lattice=\"");
    for r in 0..3 {
        for c in 0..3 {
            if r + c > 0 {
                header.push(' ');
            }
            num(if r == c { l[r] } else { 0.0 }, &mut header);
        }
    }
    header.push_str("\" Origin=\"");
    for a in 0..3 {
        if a > 0 {
            header.push(' ');
        }
        num(frame.lo[a], &mut header);
    }
    let pbc: Vec<&str> = frame
        .periodic
        .iter()
        .map(|&p| if p { "T" } else { "F" })
        .collect();
    header.push_str(&format!("\" pbc=\"{}\" Time=", pbc.join(" ")));
    num(time, &mut header);
    header.push_str(&format!(
        " Step={} Properties=species:S:1:id:I:1:type:I:1:pos:R:3:velo:R:3:forces:R:3",
        frame.step
    ));
    writeln!(out, "{count}\n{header}")
}

/// Writes one extended XYZ line per particle of `frame`: species `X`, id, type,
/// position, velocity, force.
pub fn write_xyz_rows<W: Write + ?Sized>(out: &mut W, frame: &Frame) -> io::Result<()> {
    let mut line = String::new();
    for k in 0..frame.ids.len() {
        line.clear();
        line.push_str(&format!("X {} {}", frame.ids[k], frame.types[k]));
        for v in [&frame.positions[k], &frame.velocities[k], &frame.forces[k]] {
            for x in v {
                line.push(' ');
                format_g17(*x, &mut line);
            }
        }
        line.push('\n');
        out.write_all(line.as_bytes())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame<'a>(energies: Option<&'a [f64]>) -> Frame<'a> {
        Frame {
            step: 10,
            lo: [0.0, 0.0, 0.0],
            hi: [8.397980956912537, 2.0, 3.0],
            periodic: [true, true, false],
            ids: &[1, 2],
            types: &[1, 2],
            positions: &[[0.1, 0.2, 0.3], [1.0, 2.0, 3.0]],
            velocities: &[[0.0; 3], [1.0, -1.0, 0.5]],
            forces: &[[1e-20, 0.0, 0.0], [0.0; 3]],
            energies,
            masses: Some(&[2.0, 3.0]),
            accelerations: Some(&[[0.5, 0.0, 0.0], [0.0, 0.0, -1.0]]),
            potentials: Some(&[-1.0, -2.5]),
        }
    }

    /// A whole LAMMPS frame: its head and its rows.
    fn write_lammps_frame(out: &mut Vec<u8>, frame: &Frame, columns: &[String]) -> io::Result<()> {
        write_lammps_head(out, frame, frame.ids.len(), columns)?;
        write_lammps_rows(out, frame, columns)
    }

    /// Rows `range` of `frame`, with its step and box.
    fn block<'a>(frame: &Frame<'a>, range: std::ops::Range<usize>) -> Frame<'a> {
        let r = range;
        Frame {
            ids: &frame.ids[r.clone()],
            types: &frame.types[r.clone()],
            positions: &frame.positions[r.clone()],
            velocities: &frame.velocities[r.clone()],
            forces: &frame.forces[r.clone()],
            energies: frame.energies.map(|e| &e[r.clone()]),
            masses: frame.masses.map(|m| &m[r.clone()]),
            accelerations: frame.accelerations.map(|a| &a[r.clone()]),
            potentials: frame.potentials.map(|p| &p[r]),
            ..*frame
        }
    }

    #[test]
    fn lammps_frame_layout() {
        let mut out = Vec::new();
        let cols: Vec<String> = ["id", "type", "x", "fx", "pe"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        write_lammps_frame(&mut out, &frame(Some(&[-1.5, 2.0])), &cols).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(
            text,
            "ITEM: TIMESTEP\n10\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS pp pp ff\n\
             0.0000000000000000e+00 8.3979809569125372e+00\n\
             0.0000000000000000e+00 2.0000000000000000e+00\n\
             0.0000000000000000e+00 3.0000000000000000e+00\n\
             ITEM: ATOMS id type x fx pe\n1 1 0.10000000000000001 9.9999999999999995e-21 -1.5\n2 2 1 0 2\n"
        );
    }

    #[test]
    fn box_bounds_print_infinities_as_c_does() {
        assert_eq!(format_e16(f64::INFINITY), "inf");
        assert_eq!(format_e16(f64::NEG_INFINITY), "-inf");
        assert_eq!(format_e16(f64::NAN), "nan");
        assert_eq!(format_e16(-0.5), "-5.0000000000000000e-01");
    }

    #[test]
    fn gravity_columns() {
        let mut out = Vec::new();
        let cols: Vec<String> = ["id", "mass", "ax", "az", "phi"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        write_lammps_frame(&mut out, &frame(None), &cols).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(
            text.ends_with("ITEM: ATOMS id mass ax az phi\n1 2 0.5 0 -1\n2 3 0 -1 -2.5\n"),
            "{text}"
        );
    }

    #[test]
    fn a_frame_written_in_blocks_is_the_whole_frame() {
        let cols: Vec<String> = DUMP_COLUMNS.iter().map(|s| s.to_string()).collect();
        let whole = frame(Some(&[-1.5, 2.0]));
        let mut one = Vec::new();
        write_lammps_frame(&mut one, &whole, &cols).unwrap();
        let mut blocks = Vec::new();
        write_lammps_head(&mut blocks, &block(&whole, 0..1), 2, &cols).unwrap();
        for r in [0..1, 1..2] {
            write_lammps_rows(&mut blocks, &block(&whole, r), &cols).unwrap();
        }
        assert_eq!(String::from_utf8(blocks), String::from_utf8(one));
        let mut one = Vec::new();
        write_xyz_head(&mut one, &whole, 2, 0.5).unwrap();
        write_xyz_rows(&mut one, &whole).unwrap();
        let mut blocks = Vec::new();
        write_xyz_head(&mut blocks, &block(&whole, 0..0), 2, 0.5).unwrap();
        for r in [0..1, 1..2] {
            write_xyz_rows(&mut blocks, &block(&whole, r)).unwrap();
        }
        assert_eq!(String::from_utf8(blocks), String::from_utf8(one));
    }

    #[test]
    fn xyz_frame_layout() {
        let mut out = Vec::new();
        write_xyz_head(&mut out, &frame(None), 2, 0.05).unwrap();
        write_xyz_rows(&mut out, &frame(None)).unwrap();
        let text = String::from_utf8(out).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "2");
        assert!(lines[1].starts_with("Lattice=\"8.3979809569125372 0 0 0 2 0 0 0 3\" Origin=\"0 0 0\" pbc=\"T T F\" Time=0.050000000000000003 Step=10 Properties=species:S:1:id:I:1:type:I:1:pos:R:3:velo:R:3:forces:R:3"), "{}", lines[1]);
        assert_eq!(lines[3], "X 2 2 1 2 3 1 -1 0.5 0 0 0");
    }

    #[test]
    fn e16_matches_c() {
        assert_eq!(format_e16(-0.7695951608993502), "-7.6959516089935021e-01");
        assert_eq!(format_e16(24.627045148779207), "2.4627045148779207e+01");
        assert_eq!(format_e16(1e-300), "1.0000000000000000e-300");
    }
}
