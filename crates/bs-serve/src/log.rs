//! The server's log: one line per connection, message and update, written whole (lines from
//! several client threads never interleave) and flushed at once, so a supervising process
//! reads them as they happen.

use std::io::Write;
use std::sync::{Arc, Mutex};

/// Where the log's lines go.
#[derive(Clone)]
pub struct Log {
    sink: Arc<Mutex<Box<dyn Write + Send>>>,
}

impl std::fmt::Debug for Log {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Log")
    }
}

impl Log {
    /// A log to standard output.
    pub fn stdout() -> Log {
        Log::to(Box::new(std::io::stdout()))
    }

    /// A log to `w`.
    pub fn to(w: Box<dyn Write + Send>) -> Log {
        Log { sink: Arc::new(Mutex::new(w)) }
    }

    /// Writes `text` and a newline, flushed (a log that cannot be written is dropped: the
    /// server goes on).
    pub fn line(&self, text: &str) {
        let mut w = self.sink.lock().unwrap_or_else(|e| e.into_inner());
        let _ = writeln!(w, "{text}").and_then(|()| w.flush());
    }
}
