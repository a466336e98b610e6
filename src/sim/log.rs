//! Where a run's records go ([`RunLog`]): every record (`Vec<Record<N>>`), an evenly spaced subset of bounded size
//! ([`Decimated`]), none ([`SummaryOnly`]) or a stream of JSON lines to a writer ([`JsonLines`]).

use super::Record;

/// Where the records of a run go, one per iteration, as they are made (observers, not an unbounded
/// log): the caller chooses how much of a run it keeps.
///
/// `Vec<Record<N>>` keeps every record (memory grows with the run: for figures of runs of bounded length),
/// [`Decimated`] an evenly spaced subset of bounded size, [`SummaryOnly`] nothing, [`JsonLines`] streams every record
/// to a writer. The [`Run`](super::Run) returned by [`simulate_with`](super::simulate_with) has the summary of the run
/// whatever the log keeps.
pub trait RunLog<const N: usize> {
    /// Receives the record of one iteration, in order.
    ///
    /// # Errors
    /// A log that cannot keep the record (an I/O error) returns its message; the run stops with
    /// [`SimError::Log`](super::SimError::Log).
    fn record(&mut self, record: &Record<N>) -> Result<(), String>;
}

/// Every record: memory grows with the run (about 1 KB per iteration with four tasks).
impl<const N: usize> RunLog<N> for Vec<Record<N>> {
    fn record(&mut self, record: &Record<N>) -> Result<(), String> {
        self.push(record.clone());
        Ok(())
    }
}

/// No record: the [`Run`](super::Run)'s summary only, constant memory.
#[derive(Debug, Clone, Copy, Default)]
pub struct SummaryOnly;

impl<const N: usize> RunLog<N> for SummaryOnly {
    fn record(&mut self, _: &Record<N>) -> Result<(), String> {
        Ok(())
    }
}

/// At most `capacity` records, evenly spaced: the records of the iterations that are multiples of a stride, the
/// stride starting at 1 and doubling (every other record kept dropped) whenever the log is full. Memory is bounded by
/// `capacity` records for any run length; a run of `n` iterations keeps between `capacity/2` and `capacity` of them
/// (all of them when `n ≤ capacity`).
#[derive(Debug, Clone, PartialEq)]
pub struct Decimated<const N: usize> {
    capacity: usize,
    stride: usize,
    records: Vec<Record<N>>,
}

impl<const N: usize> Decimated<N> {
    /// A log keeping at most `capacity` records (at least 2: the stride doubles by halving a full log).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(2);
        Self {
            capacity,
            stride: 1,
            records: Vec::with_capacity(capacity),
        }
    }

    /// The records kept, in iteration order.
    pub fn records(&self) -> &[Record<N>] {
        &self.records
    }

    /// The current stride: the records kept are those of the iterations that are multiples of it.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The records kept.
    pub fn into_records(self) -> Vec<Record<N>> {
        self.records
    }
}

impl<const N: usize> RunLog<N> for Decimated<N> {
    fn record(&mut self, record: &Record<N>) -> Result<(), String> {
        if !record.iteration.is_multiple_of(self.stride) {
            return Ok(());
        }
        if self.records.len() == self.capacity {
            self.stride *= 2;
            let stride = self.stride;
            self.records.retain(|r| r.iteration.is_multiple_of(stride));
            if !record.iteration.is_multiple_of(stride) {
                return Ok(());
            }
        }
        self.records.push(record.clone());
        Ok(())
    }
}

/// Every record streamed to a writer as one JSON object per line (the fields of [`Record`]; `q`, `velocity` as
/// arrays). Memory is that of the writer's buffer: give it a `BufWriter` around a file.
#[derive(Debug)]
pub struct JsonLines<W: std::io::Write> {
    writer: W,
}

impl<W: std::io::Write> JsonLines<W> {
    /// A log writing to `writer`.
    pub fn new(writer: W) -> Self {
        Self { writer }
    }

    /// The writer, flushed.
    ///
    /// # Errors
    /// The writer's flush error.
    pub fn into_inner(mut self) -> std::io::Result<W> {
        self.writer.flush()?;
        Ok(self.writer)
    }
}

impl<const N: usize, W: std::io::Write> RunLog<N> for JsonLines<W> {
    fn record(&mut self, record: &Record<N>) -> Result<(), String> {
        serde_json::to_writer(&mut self.writer, record).map_err(|e| e.to_string())?;
        self.writer.write_all(b"\n").map_err(|e| e.to_string())
    }
}
