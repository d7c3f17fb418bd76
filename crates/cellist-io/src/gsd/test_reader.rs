//! Reading a GSD file back in the tests, checked as the GSD C reader checks one.

use std::path::Path;

use super::file::{Entry, Header};

/// A GSD file read back and checked the way the GSD C reader checks one.
pub(super) struct Parsed {
    pub(super) header: Header,
    pub(super) names: Vec<String>,
    pub(super) index: Vec<Entry>,
    pub(super) bytes: Vec<u8>,
}

pub(super) fn read(path: &Path) -> Parsed {
    let bytes = std::fs::read(path).unwrap();
    let size = bytes.len() as u64;
    let header = Header::decode((&bytes[..256]).try_into().unwrap()).unwrap();
    assert!(header.index_within(size) && header.namelist_within(size));
    let nl = header.namelist_location as usize;
    let names_block = &bytes[nl..nl + header.namelist_bytes().unwrap() as usize];
    assert_eq!(*names_block.last().unwrap(), 0, "name list 0-terminated");
    let names: Vec<String> = names_block
        .split(|&b| b == 0)
        .take_while(|n| !n.is_empty())
        .map(|n| String::from_utf8(n.to_vec()).unwrap())
        .collect();
    let il = header.index_location as usize;
    let block = &bytes[il..il + header.index_bytes().unwrap() as usize];
    let all: Vec<Entry> = block.chunks_exact(32).map(Entry::decode).collect();
    let used = all.iter().take_while(|e| e.location != 0).count();
    assert!(
        all[used..].iter().all(|e| e.encode() == [0; 32]),
        "zeros after the index"
    );
    let index = all[..used].to_vec();
    for pair in index.windows(2) {
        assert!(
            (pair[0].frame, pair[0].id) < (pair[1].frame, pair[1].id),
            "sorted"
        );
    }
    for e in &index {
        assert!(e.end().unwrap() <= size && e.location != 0);
        assert!(e.frame < header.index_allocated);
        assert!((e.id as usize) < names.len());
        assert_eq!(e.flags, 0);
    }
    Parsed {
        header,
        names,
        index,
        bytes,
    }
}

impl Parsed {
    pub(super) fn frames(&self) -> u64 {
        self.index.last().map_or(0, |e| e.frame + 1)
    }

    /// The entry and bytes of chunk `name` in `frame`, by binary search as the
    /// GSD reader finds it.
    pub(super) fn chunk(&self, frame: u64, name: &str) -> Option<(Entry, &[u8])> {
        let id = self.names.iter().position(|n| n == name)? as u16;
        let i = self
            .index
            .binary_search_by_key(&(frame, id), |e| (e.frame, e.id))
            .ok()?;
        let e = self.index[i];
        let at = e.location as usize;
        Some((e, &self.bytes[at..at + e.bytes().unwrap() as usize]))
    }

    pub(super) fn f32s(&self, frame: u64, name: &str) -> Vec<f32> {
        let (_, b) = self.chunk(frame, name).unwrap();
        b.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }

    pub(super) fn f64s(&self, frame: u64, name: &str) -> Vec<f64> {
        let (_, b) = self.chunk(frame, name).unwrap();
        b.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }

    pub(super) fn u64s(&self, frame: u64, name: &str) -> Vec<u64> {
        let (_, b) = self.chunk(frame, name).unwrap();
        b.chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    }
}
