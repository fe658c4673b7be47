//! The answers to an update, in the order the surgeon needs them, each made just before it
//! is sent: IMAGE `WarpedImage` (the pre-operative image warped into the new configuration,
//! float32 on its own grid, IJK-to-RAS), with `--uncertainty` IMAGE `Uncertainty` (total σ
//! of the fitted answer in mm on the same grid, zero outside the brain), IMAGE
//! `DisplacementField` (d(y) = X(y) − y, RAS
//! mm, three components), POLYDATA `DeformedBrain` (the deformed boundary, RAS mm) and
//! STRING `Report` (report.json's keys plus `serve`: the seconds of each part and the map's
//! account of the space between brain and skull). Every message goes out in the header
//! version the client last sent ([`Wire`]).

use std::io::Write;
use std::time::Instant;

use bs_igtl::messages::image::RAS;
use bs_igtl::{Cells, Encode, Envelope, Image, PolyData, Text};
use serde_json::{Value, json};

use crate::state::{Brainshift, Solution};

/// How a client is answered: the header version it last sent, and version 2's message ids.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wire {
    /// 1, or 2.
    pub version: u16,
    /// The next message id (version 2).
    pub next_id: u32,
}

impl Default for Wire {
    fn default() -> Wire {
        Wire { version: 1, next_id: 1 }
    }
}

/// Why the replies stopped.
#[derive(Debug)]
pub enum ReplyError {
    /// The client is gone.
    Gone(std::io::Error),
    /// A reply could not be made (answered with `Error`; the session keeps its state).
    Make(String),
}

/// Sends `message` as device `device` to `out`, framed as `wire` says; the bytes sent.
pub fn send<M: Encode, W: Write>(
    out: &mut W,
    wire: &mut Wire,
    device: &str,
    message: &M,
) -> Result<usize, ReplyError> {
    let envelope = Envelope {
        version: wire.version,
        device,
        timestamp: bs_igtl::header::now(),
        message_id: wire.next_id,
        metadata: &[],
    };
    let packed = bs_igtl::pack_message(message, &envelope)
        .map_err(|e| ReplyError::Make(format!("{device}: {e}")))?;
    wire.next_id = wire.next_id.wrapping_add(1);
    packed.write_to(out).map_err(ReplyError::Gone)?;
    Ok(packed.len())
}

/// Sends an `Error` with `text` (cut to what a STRING holds).
pub fn send_error<W: Write>(out: &mut W, wire: &mut Wire, text: &str) -> Result<usize, ReplyError> {
    send(out, wire, "Error", &Text::cut(text))
}

/// What the replies to one update cost, seconds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Solve and verification.
    pub solve: f64,
    /// Inverse map and warp of the image, from the solve's end.
    pub image: f64,
    /// Framing (CRC) and sending of the WarpedImage.
    pub send_warped: f64,
    /// Extension iterations of the map between brain and skull.
    pub extension_iterations: usize,
}

/// `values` as little-endian bytes in `buffer` (resized, not reallocated once large
/// enough), converted in parallel pieces.
fn le_bytes<'b>(values: &[f32], buffer: &'b mut Vec<u8>) -> &'b [u8] {
    use rayon::prelude::*;
    const PIECE: usize = 1 << 16;
    buffer.resize(4 * values.len(), 0);
    buffer.par_chunks_mut(4 * PIECE).zip(values.par_chunks(PIECE)).for_each(|(out, v)| {
        for (o, x) in out.chunks_exact_mut(4).zip(v) {
            o.copy_from_slice(&x.to_le_bytes());
        }
    });
    buffer
}

/// The grid's size as the IMAGE header's u16 fields.
fn size(dims: [usize; 3]) -> Result<[u16; 3], ReplyError> {
    let mut s = [0u16; 3];
    for k in 0..3 {
        s[k] = u16::try_from(dims[k]).map_err(|_| {
            ReplyError::Make(format!("an image of {dims:?} voxels: IMAGE sizes are at most 65535"))
        })?;
    }
    Ok(s)
}

/// Sends every reply to `solution` (see the module documentation); `buffer` holds the
/// voxels' bytes (reused between updates).
pub fn answer<W: Write>(
    bs: &Brainshift,
    solution: &Solution,
    options: (bool, bool),
    out: &mut W,
    wire: &mut Wire,
    buffer: &mut Vec<u8>,
) -> Result<Timing, ReplyError> {
    let (field, surface) = options;
    let started = Instant::now();
    let (map, gap) = bs.map(&solution.result).map_err(ReplyError::Make)?;
    let grid = &bs.image.grid;
    let dims = size(grid.dims())?;
    let m = grid.voxel_to_world();
    let ijk_to_ras: [[f64; 4]; 4] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]));
    let warped = bs.install(|| map.warp_with_gap(&bs.image, &bs.image.data, gap.as_deref()));
    let image_seconds = started.elapsed().as_secs_f64();
    let sent = Instant::now();
    let bytes = bs.install(|| le_bytes(&warped, buffer));
    let image = Image::float32_le(dims, 1, &ijk_to_ras, RAS, bytes)
        .map_err(|e| ReplyError::Make(e.to_string()))?;
    send(out, wire, "WarpedImage", &image)?;
    let send_warped = sent.elapsed().as_secs_f64();
    drop(warped);
    if let Some(sigma) = &solution.sigma {
        let s = bs.install(|| map.nodal(sigma));
        let bytes = bs.install(|| le_bytes(&s, buffer));
        let image = Image::float32_le(dims, 1, &ijk_to_ras, RAS, bytes)
            .map_err(|e| ReplyError::Make(e.to_string()))?;
        send(out, wire, "Uncertainty", &image)?;
    }
    if field {
        let d: Vec<f32> =
            bs.install(|| map.field_with_gap(gap.as_deref())).into_iter().flatten().collect();
        let bytes = bs.install(|| le_bytes(&d, buffer));
        let image = Image::float32_le(dims, 3, &ijk_to_ras, RAS, bytes)
            .map_err(|e| ReplyError::Make(e.to_string()))?;
        send(out, wire, "DisplacementField", &image)?;
    }
    if surface {
        send(out, wire, "DeformedBrain", &deformed_brain(bs, solution))?;
    }
    let outside = map.outside_report();
    let timing = Timing {
        solve: solution.solve_seconds,
        image: image_seconds,
        send_warped,
        extension_iterations: outside.as_ref().map_or(0, |o| o.iterations),
    };
    let report = report_json(solution, &timing, outside.as_ref());
    send(out, wire, "Report", &Text::cut(&report.to_string()))?;
    Ok(timing)
}

/// The deformed brain surface in RAS mm.
fn deformed_brain(bs: &Brainshift, solution: &Solution) -> PolyData {
    let s = &solution.surface.surface;
    let points = s.vertices.iter().map(|p| bs.frame.to_ras(p).map(|x| x as f32)).collect();
    let triangles: Vec<[u32; 3]> = s.triangles.iter().map(|t| t.map(|k| k as u32)).collect();
    PolyData { points, polygons: Cells::triangles(&triangles), ..PolyData::default() }
}

/// The Report's JSON: the run's report and `serve`.
fn report_json(
    solution: &Solution,
    t: &Timing,
    outside: Option<&bs_register::outside::OutsideReport>,
) -> Value {
    let mut r = serde_json::to_value(&solution.report).unwrap_or_else(|_| json!({}));
    let outside = outside.map(|o| {
        let boundary = match o.boundary {
            bs_register::outside::Boundary::Skull => json!("skull"),
            bs_register::outside::Boundary::Band(w) => json!(w),
        };
        json!({
            "boundary": boundary,
            "gap_voxels": o.gap_voxels,
            "iterations": o.iterations,
            "residual": o.residual,
            "folding_voxels": o.folding.non_positive,
            "min_det": o.folding.min,
            "min_det_at": o.worst_at,
        })
    });
    if let Value::Object(m) = &mut r {
        m.insert(
            "serve".into(),
            json!({
                "solve_seconds": t.solve,
                "image_seconds": t.image,
                "warped_image_send_seconds": t.send_warped,
                "outside": outside,
            }),
        );
    }
    r
}
