//! brainshift in the operating room: `brainshift serve`, a native OpenIGTLink server (3D
//! Slicer's OpenIGTLinkIF, PLUS, navigation systems) over a live, in-memory session of a
//! scene. The scene is prepared and the pre-operative image read once; each measurement a
//! client sends becomes a typed `bs_scene::Update` ([`measure`], in the scene's frame and
//! unit: [`frame`]), is solved warm from the last good state ([`state`]) and answered to that
//! client ([`replies`]: the warped image first). Protocol bytes are bs-igtl's; the
//! connection loop is [`client`], the listener and its threads [`server`], the options
//! (declared once, for the binary and the Python package) [`options`].
//!
//! Files:
//! * `options.rs`: `Options` and `Command`, declared once with clap;
//! * `server.rs`: `Server` and `run`: the listener, one thread per client, the client cap,
//!   Ctrl-C;
//! * `shared.rs`: what the listener and the client threads share;
//! * `client.rs`: one connection's loop;
//! * `measure.rs`: a message turned into a typed `bs_scene::Update`, stored landmarks, or a
//!   refusal;
//! * `frame.rs`: `Frame`, RAS millimetres on the wire to the scene's frame and unit;
//! * `state.rs`: the session, the image read once and its pre-operative gap cached;
//! * `replies.rs`: WarpedImage, Uncertainty (with `--uncertainty`), DisplacementField,
//!   DeformedBrain and Report;
//! * `log.rs`: `Log`, one whole line per connection, message and update.
//!
//! Architecture invariant: a front end like bs-cli: it drives `bs_scene::Session` and
//! bs-register's inverse map, never the solver or the composition; protocol bytes are
//! bs-igtl's.
//!
//! Nothing the clients send stops the server: a refused measurement, a load the solver
//! cannot carry or a result that fails verification is answered with STRING `Error` and the
//! session stays at its last good state; a stream that cannot be read on is answered and
//! that connection closed.

pub mod client;
pub mod frame;
pub mod log;
pub mod measure;
pub mod options;
pub mod replies;
pub mod server;
pub mod shared;
pub mod state;

pub use log::Log;
pub use options::{Command, Options};
pub use server::{Server, run};
