//! GSD trajectory files (file layer 2.x: the format of HOOMD-blue, read by OVITO,
//! freud, MDAnalysis and the `gsd` Python package), written a frame at a time, and
//! frames of its `hoomd` schema.
//!
//! A GSD file (all numbers little-endian) holds a 256-byte header at offset 0, an
//! index block of 32-byte entries (one per data chunk: frame, rows, location,
//! columns, name id, type), a name list block (names ended by a 0 byte, the list
//! ended by an empty name, the block a multiple of 64 bytes) and the chunks' bytes.
//! Readers find a chunk by binary search over the whole index, so the entries are
//! sorted by frame and, within a frame, by name id; the first entry whose location
//! is 0 ends the index. A block that fills up is written again, twice as large, at
//! the end of the file, and the header is pointed at the copy.

// The file layer: `file` (header, index entries, element types, block reads and
// writes), `writer` (GsdWriter) and `resume` (GsdWriter::resume); the schema on
// top of it: `hoomd`.
mod file;
mod hoomd;
mod resume;
#[cfg(test)]
mod test_reader;
mod writer;

pub use file::GsdData;
pub use hoomd::{write_hoomd_frame, HoomdBlocks, HoomdFrame, HoomdHead, HoomdRows};
pub use writer::GsdWriter;
