//! One connection: messages read one after the other, each answered in the header version
//! the client last sent. A message that cannot be taken (a bad checksum, unreadable
//! content, a refused measurement, an update the solver cannot carry) is answered with
//! `Error` and the connection goes on; a stream that cannot be read on (a bad header, an
//! oversize, truncated or stalled body) is answered and closed. A client that leaves in the
//! middle of an update costs nothing but that update's replies.

use std::net::TcpStream;
use std::time::Instant;

use bs_igtl::{FrameError, Message};

use crate::measure::{Asked, Preop, asked};
use crate::replies::{ReplyError, Wire, answer, send_error};
use crate::shared::Shared;

/// What one client keeps between its messages.
#[derive(Debug, Default)]
struct Client {
    wire: Wire,
    preop: Option<Preop>,
    buffer: Vec<u8>,
}

/// Serves the connection `stream` (client `name`) until it closes or the server stops.
pub fn serve(shared: &Shared, mut stream: TcpStream, name: &str) {
    let mut c = Client::default();
    let (max_body, stall) = (shared.options.max_body(), shared.options.stall());
    loop {
        let (header, body) = match bs_igtl::read_message(&mut stream, max_body, stall) {
            Ok(Some(m)) => m,
            Ok(None) => return,
            Err(FrameError::Io(_)) if shared.stopping() => return,
            Err(FrameError::Io(e)) => {
                shared.log.line(&format!("  {name}: {e}"));
                return;
            }
            Err(e) => {
                let _ = error(
                    shared,
                    &mut stream,
                    &mut c.wire,
                    &format!("{e}; closing the connection"),
                );
                return;
            }
        };
        shared.log.line(&format!("{name}: {header}, {} bytes", header.body_size));
        let started = Instant::now();
        let m = match Message::new(header.clone(), body) {
            Ok(m) => m,
            Err(e) => {
                c.wire.version = header.version;
                if error(shared, &mut stream, &mut c.wire, &format!("{header}: {e}")).is_err() {
                    return;
                }
                continue;
            }
        };
        c.wire.version = m.header.version;
        match one(shared, &mut stream, &mut c, &m) {
            Ok(true) => {
                shared.log.line(&format!("  replied in {:.2} s", started.elapsed().as_secs_f64()))
            }
            Ok(false) => {}
            Err(()) => return,
        }
    }
}

/// Answers one message; `Ok(true)` when an update was answered, `Err` when the client is
/// gone.
fn one(shared: &Shared, stream: &mut TcpStream, c: &mut Client, m: &Message) -> Result<bool, ()> {
    let bs = &shared.brainshift;
    let updates = match asked(&bs.offer(), c.preop.as_ref(), m) {
        Ok(Asked::Nothing(line)) => {
            shared.log.line(&line);
            return Ok(false);
        }
        Ok(Asked::Stored(preop, line)) => {
            shared.log.line(&line);
            c.preop = Some(preop);
            return Ok(false);
        }
        Ok(Asked::Update(updates, line)) => {
            shared.log.line(&line);
            updates
        }
        Err(text) => return error(shared, stream, &mut c.wire, &text).map(|_| false),
    };
    let solution = match bs.solve(&updates) {
        Ok(s) => s,
        Err(e) => {
            let text = format!("{e}; the session keeps its last good state");
            return error(shared, stream, &mut c.wire, &text).map(|_| false);
        }
    };
    let o = &shared.options;
    match answer(bs, &solution, (!o.no_field, !o.no_surface), stream, &mut c.wire, &mut c.buffer) {
        Ok(t) => {
            let r = &solution.report;
            shared.log.line(&format!(
                "  solved in {:.2} s ({} Newton, {} GMRES, max displacement {:.2} {}); WarpedImage \
                 made {:.2} s later and sent in {:.3} s ({} extension iterations)",
                t.solve,
                r.steps,
                r.linear_iterations,
                r.max_displacement,
                r.units.map_or("", |u| u.symbol()),
                t.image,
                t.send_warped,
                t.extension_iterations
            ));
            Ok(true)
        }
        Err(ReplyError::Gone(e)) => {
            shared.log.line(&format!("  could not send the reply ({e}); the client is gone"));
            Err(())
        }
        Err(ReplyError::Make(e)) => {
            error(shared, stream, &mut c.wire, &format!("could not make the reply: {e}"))
                .map(|_| false)
        }
    }
}

/// Answers `text` with `Error` (and logs it); `Err` when the client is gone.
fn error(shared: &Shared, stream: &mut TcpStream, wire: &mut Wire, text: &str) -> Result<(), ()> {
    shared.log.line(&format!("  error: {text}"));
    send_error(stream, wire, text).map(|_| ()).map_err(|_| ())
}
