//! What a frame cost: the march's work counters and the passes' GPU times (timestamp queries,
//! where the adapter has trustworthy ones). Read synchronously for headless frames, or a frame
//! or two late for the window, which must never wait on the GPU for them.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

use serde::Serialize;

use super::gpu::Gpu;
use super::march::Counters;
use super::{readback, RenderError};

/// Work the march did, from the GPU's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Stats {
    pub rays: u64,
    pub steps: u64,
    pub density_samples: u64,
    pub detail_samples: u64,
    pub light_samples: u64,
    /// Density samples taken outside the map's region (zero with region culling on).
    pub outside_samples: u64,
    pub skipped_steps: u64,
    pub early_exits: u64,
    /// Rays the driver stopped before their march ended (Mesa llvmpipe's cap on a shader's loop
    /// iterations; only `reference`'s long rays reach it). Zero on a GPU.
    pub cut_rays: u64,
    /// Pixels that took more rays than their first, in the march's second dispatch (a limb's
    /// or a silhouette's split, a grazing pixel's extra rays).
    pub reworked: u64,
}

impl From<Counters> for Stats {
    fn from(c: Counters) -> Stats {
        Stats {
            rays: c.rays.into(),
            steps: c.steps.into(),
            density_samples: c.density_samples.into(),
            detail_samples: c.detail_samples.into(),
            light_samples: c.light_samples.into(),
            outside_samples: c.outside_samples.into(),
            skipped_steps: c.skipped_steps.into(),
            early_exits: c.early_exits.into(),
            cut_rays: c.cut_rays.into(),
            reworked: c.reworked.into(),
        }
    }
}

/// One frame's counters and GPU pass times (`None` without timestamps: CPU drivers).
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameStats {
    pub stats: Stats,
    pub march_ms: Option<f64>,
    pub present_ms: Option<f64>,
}

impl FrameStats {
    /// March + present GPU time, where both were timed.
    pub fn gpu_ms(&self) -> Option<f64> {
        self.march_ms.zip(self.present_ms).map(|(a, b)| a + b)
    }
}

const COUNTERS_BYTES: u64 = std::mem::size_of::<Counters>() as u64;
/// Where the timestamps sit in a stats copy: after the counters, 8-byte aligned.
const TIMES_AT: u64 = COUNTERS_BYTES.next_multiple_of(8);
const TIMES_BYTES: u64 = 4 * 8;

/// Timestamp queries around the march and present passes.
pub struct PassTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    period_ns: f64,
}

impl PassTimer {
    pub fn new(gpu: &Gpu) -> PassTimer {
        PassTimer {
            set: gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass times"),
                ty: wgpu::QueryType::Timestamp,
                count: 4,
            }),
            resolve: gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("pass times"),
                size: TIMES_BYTES,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: gpu.queue.get_timestamp_period() as f64,
        }
    }

    pub fn compute_writes(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: Some(1),
        }
    }

    /// The compute span split over two passes: its start written by the first (the march),
    /// its end by the second (the reproject stage), so a reprojected frame's march time
    /// includes its reprojection.
    pub fn compute_start(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(0),
            end_of_pass_write_index: None,
        }
    }

    pub fn compute_end(&self) -> wgpu::ComputePassTimestampWrites<'_> {
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: None,
            end_of_pass_write_index: Some(1),
        }
    }

    pub fn render_writes(&self) -> wgpu::RenderPassTimestampWrites<'_> {
        wgpu::RenderPassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2),
            end_of_pass_write_index: Some(3),
        }
    }

    pub fn resolve(&self, enc: &mut wgpu::CommandEncoder) {
        enc.resolve_query_set(&self.set, 0..4, &self.resolve, 0);
    }

    /// (march, present) milliseconds from the four resolved timestamps.
    fn times(&self, raw: &[u8]) -> (Option<f64>, Option<f64>) {
        let ts: Vec<u64> = bytemuck::pod_collect_to_vec(raw);
        let ms = |a: u64, b: u64| (b > a).then(|| (b - a) as f64 * self.period_ns / 1e6);
        match ts[..] {
            [a, b, c, d] => (ms(a, b), ms(c, d)),
            _ => (None, None),
        }
    }
}

/// Counters and pass times out of one copy laid out as [`record_copy`] writes it.
fn parse(raw: &[u8], timer: Option<&PassTimer>) -> FrameStats {
    let counters: Counters = raw
        .get(..COUNTERS_BYTES as usize)
        .map(bytemuck::pod_read_unaligned)
        .unwrap_or_default();
    let (march_ms, present_ms) = match (timer, raw.get(TIMES_AT as usize..)) {
        (Some(t), Some(times)) if times.len() >= TIMES_BYTES as usize => {
            t.times(&times[..TIMES_BYTES as usize])
        }
        _ => (None, None),
    };
    FrameStats {
        stats: counters.into(),
        march_ms,
        present_ms,
    }
}

fn copy_buffer_size() -> u64 {
    TIMES_AT + TIMES_BYTES
}

fn record_copy(
    enc: &mut wgpu::CommandEncoder,
    counters: &wgpu::Buffer,
    timer: Option<&PassTimer>,
    dst: &wgpu::Buffer,
) {
    enc.copy_buffer_to_buffer(counters, 0, dst, 0, COUNTERS_BYTES);
    if let Some(t) = timer {
        enc.copy_buffer_to_buffer(&t.resolve, 0, dst, TIMES_AT, TIMES_BYTES);
    }
}

fn staging(gpu: &Gpu) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("frame stats"),
        size: copy_buffer_size(),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The last submitted frame's statistics, waiting for the GPU to finish it.
pub fn read_now(
    gpu: &Gpu,
    counters: &wgpu::Buffer,
    timer: Option<&PassTimer>,
) -> Result<FrameStats, RenderError> {
    let dst = staging(gpu);
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    record_copy(&mut enc, counters, timer, &dst);
    gpu.queue.submit([enc.finish()]);
    let raw = readback::Pending::whole(dst).finish(gpu)?;
    Ok(parse(&raw, timer))
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SlotState {
    Free,
    /// A copy is recorded into it; mapping starts after the submit.
    Recorded,
    /// Mapping requested; `ready` says when it is done.
    Mapping,
}

/// Where a slot's map request stands (shared with its callback).
const PENDING: u8 = 0;
const MAPPED: u8 = 1;
const FAILED: u8 = 2;

struct Slot {
    buffer: wgpu::Buffer,
    state: SlotState,
    mapped: Arc<AtomicU8>,
    /// Frame order, so the newest finished copy wins.
    seq: u64,
}

/// A few staging buffers in rotation: each frame's counters are copied into a free one and
/// mapped asynchronously; a frame that finds none free simply goes unmeasured.
pub struct StatsReader {
    slots: Vec<Slot>,
    seq: u64,
    newest: u64,
}

/// Frames in flight the reader can measure at once.
const SLOTS: usize = 3;

impl StatsReader {
    pub fn new(gpu: &Gpu) -> StatsReader {
        StatsReader {
            slots: (0..SLOTS)
                .map(|_| Slot {
                    buffer: staging(gpu),
                    state: SlotState::Free,
                    mapped: Arc::new(AtomicU8::new(PENDING)),
                    seq: 0,
                })
                .collect(),
            seq: 0,
            newest: 0,
        }
    }

    pub fn record(
        &mut self,
        enc: &mut wgpu::CommandEncoder,
        counters: &wgpu::Buffer,
        timer: Option<&PassTimer>,
    ) {
        let Some(slot) = self.slots.iter_mut().find(|s| s.state == SlotState::Free) else {
            return;
        };
        self.seq += 1;
        slot.seq = self.seq;
        record_copy(enc, counters, timer, &slot.buffer);
        slot.state = SlotState::Recorded;
    }

    pub fn after_submit(&mut self) {
        for slot in self.slots.iter_mut() {
            if slot.state == SlotState::Recorded {
                slot.mapped.store(PENDING, Ordering::Release);
                let mapped = slot.mapped.clone();
                slot.buffer
                    .slice(..)
                    .map_async(wgpu::MapMode::Read, move |r| {
                        // A failed map only leaves that frame unmeasured.
                        mapped.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
                    });
                slot.state = SlotState::Mapping;
            }
        }
    }

    pub fn poll(&mut self, gpu: &Gpu, timer: Option<&PassTimer>) -> Option<FrameStats> {
        // Non-blocking: runs the callbacks of maps that have finished.
        let _ = gpu.device.poll(wgpu::PollType::Poll);
        let mut best: Option<(u64, FrameStats)> = None;
        for slot in self.slots.iter_mut() {
            if slot.state != SlotState::Mapping {
                continue;
            }
            let parsed = match slot.mapped.load(Ordering::Acquire) {
                PENDING => continue,
                MAPPED => {
                    let parsed = slot
                        .buffer
                        .slice(..)
                        .get_mapped_range()
                        .ok()
                        .map(|raw| parse(&raw, timer));
                    slot.buffer.unmap();
                    parsed
                }
                _ => None,
            };
            slot.state = SlotState::Free;
            if let Some(fs) = parsed {
                if slot.seq > self.newest && best.as_ref().is_none_or(|(s, _)| slot.seq > *s) {
                    best = Some((slot.seq, fs));
                }
            }
        }
        let (seq, fs) = best?;
        self.newest = seq;
        Some(fs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_copy_parses_back_by_field() {
        let c = Counters {
            rays: 1,
            steps: 2,
            density_samples: 3,
            detail_samples: 4,
            light_samples: 5,
            outside_samples: 6,
            skipped_steps: 7,
            early_exits: 8,
            cut_rays: 9,
            reworked: 10,
        };
        let mut raw = vec![0u8; copy_buffer_size() as usize];
        raw[..COUNTERS_BYTES as usize].copy_from_slice(bytemuck::bytes_of(&c));
        let s = parse(&raw, None).stats;
        assert_eq!(
            [
                s.rays,
                s.steps,
                s.density_samples,
                s.detail_samples,
                s.light_samples
            ],
            [1, 2, 3, 4, 5]
        );
        assert_eq!(
            [
                s.outside_samples,
                s.skipped_steps,
                s.early_exits,
                s.cut_rays,
                s.reworked
            ],
            [6, 7, 8, 9, 10]
        );
    }
}
