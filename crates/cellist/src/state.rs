//! A model's complete state as named sections of little-endian numbers, for
//! checkpoints: floats by their bit patterns, so that a restored state is the saved
//! one bit for bit. The file around the sections (magic, version, checksums) is
//! `cellist-io`'s; this module only packs and unpacks numbers, and never panics on
//! a section of the wrong size or a missing one.

use std::fmt;

/// One named section: `data` holds `len` numbers of 8 (or 4) little-endian bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Section {
    /// Name, unique within a state (`"positions"`).
    pub name: String,
    /// The bytes.
    pub data: Vec<u8>,
}

/// A saved state: sections in the order they were written.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct State {
    /// The sections.
    pub sections: Vec<Section>,
}

/// Why a state cannot be restored: a section is missing or has the wrong size.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StateError(pub String);

impl fmt::Display for StateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for StateError {}

/// A section's numbers added a block at a time, in the layout of
/// [`State::put_u64s`], [`State::put_f64s`] and [`State::put_vectors`]: the
/// same bytes as one call with all of them.
#[derive(Clone, Debug, Default)]
pub struct SectionBuilder {
    data: Vec<u8>,
}

impl SectionBuilder {
    /// An empty section with room for `values` numbers.
    pub fn with_capacity(values: usize) -> Self {
        SectionBuilder {
            data: Vec::with_capacity(8 * values),
        }
    }

    /// Appends unsigned integers.
    pub fn push_u64s(&mut self, values: impl IntoIterator<Item = u64>) {
        for v in values {
            self.data.extend_from_slice(&v.to_le_bytes());
        }
    }

    /// Appends floats as their IEEE-754 bit patterns.
    pub fn push_f64s(&mut self, values: impl IntoIterator<Item = f64>) {
        self.push_u64s(values.into_iter().map(f64::to_bits));
    }

    /// Appends fixed-size vectors component by component.
    pub fn push_vectors<const D: usize>(&mut self, values: &[[f64; D]]) {
        self.push_f64s(values.as_flattened().iter().copied());
    }
}

impl State {
    fn push(&mut self, name: &str, data: Vec<u8>) {
        debug_assert!(
            self.sections.iter().all(|s| s.name != name),
            "section {name} written twice"
        );
        self.sections.push(Section {
            name: name.to_string(),
            data,
        });
    }

    /// Adds `values` as their IEEE-754 bit patterns.
    pub fn put_f64s(&mut self, name: &str, values: impl IntoIterator<Item = f64>) {
        self.put_u64s(name, values.into_iter().map(f64::to_bits));
    }

    /// Adds fixed-size vectors (`[x, y, z]` per particle) component by component.
    pub fn put_vectors<const D: usize>(&mut self, name: &str, values: &[[f64; D]]) {
        self.put_f64s(name, values.as_flattened().iter().copied());
    }

    /// Adds unsigned integers (their bytes allocated once when the iterator
    /// knows its length, not grown by doubling).
    pub fn put_u64s(&mut self, name: &str, values: impl IntoIterator<Item = u64>) {
        let values = values.into_iter();
        let mut section = SectionBuilder::with_capacity(values.size_hint().0);
        section.push_u64s(values);
        self.put_section(name, section);
    }

    /// Adds a section built a piece at a time.
    pub fn put_section(&mut self, name: &str, section: SectionBuilder) {
        self.push(name, section.data);
    }

    /// The bytes of section `name`, whose size must be a multiple of `width`.
    fn bytes(&self, name: &str, width: usize) -> Result<&[u8], StateError> {
        let section = self
            .sections
            .iter()
            .find(|s| s.name == name)
            .ok_or_else(|| StateError(format!("the state has no section '{name}'")))?;
        if section.data.len() % width != 0 {
            return Err(StateError(format!(
                "section '{name}' has {} bytes, not a whole number of {width}-byte values",
                section.data.len()
            )));
        }
        Ok(&section.data)
    }

    /// True when the state holds a section `name`.
    pub fn has(&self, name: &str) -> bool {
        self.sections.iter().any(|s| s.name == name)
    }

    /// Section `name` as floats.
    pub fn f64s(&self, name: &str) -> Result<Vec<f64>, StateError> {
        Ok(self
            .bytes(name, 8)?
            .chunks_exact(8)
            .map(|c| f64::from_bits(u64::from_le_bytes(c.try_into().expect("8 bytes"))))
            .collect())
    }

    /// Section `name` as unsigned integers.
    pub fn u64s(&self, name: &str) -> Result<Vec<u64>, StateError> {
        Ok(self
            .bytes(name, 8)?
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
            .collect())
    }

    /// Section `name` as exactly `n` floats.
    pub fn f64s_of(&self, name: &str, n: usize) -> Result<Vec<f64>, StateError> {
        let values = self.f64s(name)?;
        expect_len(name, values.len(), n)?;
        Ok(values)
    }

    /// Section `name` as exactly `n` unsigned integers.
    pub fn u64s_of(&self, name: &str, n: usize) -> Result<Vec<u64>, StateError> {
        let values = self.u64s(name)?;
        expect_len(name, values.len(), n)?;
        Ok(values)
    }

    /// Section `name` as exactly `n` vectors of `D` components.
    pub fn vectors<const D: usize>(
        &self,
        name: &str,
        n: usize,
    ) -> Result<Vec<[f64; D]>, StateError> {
        let flat = self.f64s(name)?;
        expect_len(name, flat.len(), n * D)?;
        Ok(flat
            .chunks_exact(D)
            .map(|c| std::array::from_fn(|a| c[a]))
            .collect())
    }

    /// The single float of section `name`.
    pub fn f64(&self, name: &str) -> Result<f64, StateError> {
        Ok(self.f64s_of(name, 1)?[0])
    }

    /// The single integer of section `name`.
    pub fn u64(&self, name: &str) -> Result<u64, StateError> {
        Ok(self.u64s_of(name, 1)?[0])
    }
}

fn expect_len(name: &str, got: usize, want: usize) -> Result<(), StateError> {
    if got == want {
        Ok(())
    } else {
        Err(StateError(format!(
            "section '{name}' holds {got} numbers, expected {want}"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_round_trip_bit_for_bit() {
        let mut s = State::default();
        let odd = [0.1, -0.0, f64::MIN_POSITIVE / 4.0, f64::INFINITY, f64::NAN];
        s.put_f64s("odd", odd);
        s.put_vectors("x", &[[1.0, 2.0], [3.0, 4.5]]);
        s.put_u64s("ids", [7, u64::MAX]);
        let back = s.f64s("odd").unwrap();
        assert_eq!(
            back.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            odd.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );
        assert_eq!(s.vectors::<2>("x", 2).unwrap(), [[1.0, 2.0], [3.0, 4.5]]);
        assert_eq!(s.u64s_of("ids", 2).unwrap(), [7, u64::MAX]);
    }

    #[test]
    fn missing_and_misshapen_sections_are_errors() {
        let mut s = State::default();
        s.put_f64s("x", [1.0, 2.0, 3.0]);
        assert!(s.f64s("y").unwrap_err().0.contains("no section 'y'"));
        assert!(s.vectors::<2>("x", 1).unwrap_err().0.contains("expected 2"));
        s.sections[0].data.pop();
        assert!(s.f64s("x").unwrap_err().0.contains("whole number"));
    }
}
