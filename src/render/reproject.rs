//! Reproject stage: dispatches shaders/reproject.wgsl, which makes a full-resolution frame from
//! this frame's subset march (one pixel of each n×n cell) and the previous frame moved by the
//! camera's motion and each pixel's distance (DESIGN §4b; Guerrilla's Nubis marches 1/16 of the
//! pixels a frame). Owns the subset order and the rules for when the history no longer fits:
//! a new size or map, a teleport, a jump in time, a changed look.

use chrono::{DateTime, Utc};
use glam::DVec3;

use super::camera::Camera;
use super::contract::{self, Binding, Resource};
use super::gpu::Gpu;
use super::march::CLOUD_FORMAT;
use super::pipeline::bind;
use super::{shader, Settings};

crate::gpu_struct! {
    /// The previous frame's camera (`Reproject` in shaders/reproject.wgsl).
    pub struct ReprojectParams as "Reproject" {
        pub prev_fwd: [f32; 3],
        pub prev_tan_half_fov: f32,
        pub prev_right: [f32; 3],
        pub prev_aspect: f32,
        pub prev_view_up: [f32; 3],
        /// 0: no usable history; every pixel not marched is the fresh subset upsampled.
        pub valid: u32,
        /// The previous camera's position less this one's (ECEF m).
        pub prev_delta: [f32; 3],
        /// Relative change of a pixel's distance beyond which its history is rejected.
        pub max_depth_change: f32,
        /// 0: the camera moved since the last frame. k + 1: this is the k-th frame (from 0) the
        /// camera has stood still, whose march took the cells' pixels of rank k in the subset
        /// order: every pixel of rank ≤ k holds its own march.
        pub still: u32,
        /// A still view's pixel older than this many frames is not kept (the clouds drift
        /// while time runs): u32::MAX while the scene's time stands.
        pub max_age: u32,
        /// The still view's lattice the other pixels are filled from: every pixel at
        /// (`lattice_x`, `lattice_y`) + multiples of `lattice_step` holds its own march, none
        /// older than `max_age` ([`still_lattice`]).
        pub lattice_x: u32,
        pub lattice_y: u32,
        pub lattice_step: u32,
        /// 1: the still view began after a full march young enough: every pixel holds its own.
        pub whole: u32,
        /// A still view's weight for this frame's march of a pixel against the mean its history
        /// holds ([`still_mean_weight`]).
        pub new_weight: f32,
        pub _pad2: u32,
    }
}

/// Relative change of distance that rejects a pixel's history: the opacity-weighted distance
/// of a cloud moves a little as noise crosses the ray; an occluder moving in or out changes it
/// by far more.
pub const MAX_DEPTH_CHANGE: f32 = 0.3;
/// Farther than this between two frames is a teleport (m): a jet at Mach 2 covers 700 m a
/// frame at 1 fps.
pub const TELEPORT_M: f64 = 2_000.0;
/// Turning more than this between two frames (degrees) leaves little history on screen.
pub const TELEPORT_TURN_DEG: f64 = 30.0;
/// A still view keeps a marched pixel while the scene's time has moved less than this (s) since
/// it was marched: with time running fast (the window's ×600) a pixel marched n² frames ago
/// shows clouds that have since drifted. 600 s keeps the last 16 frames at ×600 (30 s a
/// frame at 20 fps), as many as a 4×4 cell's history held before.
pub const STILL_TIME_S: f64 = 600.0;

/// The fewest frames a pixel must stay usable ([`max_age`]) for the history to add anything:
/// a still view's first lattice finer than the subset is two whole blocks of 4 ranks, 7 frames
/// old at its oldest ([`still_lattice`]). A larger step of the scene's time a frame than
/// `STILL_TIME_S / 7` (86 s) starts afresh: the window's ×600 keeps its history down to 7 fps;
/// a time-lapse's 10 min a frame marches every frame whole (`flight`) rather than showing the
/// fresh subset enlarged over history of other weather.
pub const MIN_HISTORY_AGE: u32 = 7;

/// Every binding of reproject.wgsl.
pub const BINDINGS: &[Binding] = &[
    contract::frame(0, 0),
    contract::params(0, 1),
    b(0, 2, Resource::Sampler),
    b(1, 0, Resource::Texture2d { filterable: true }),
    b(1, 1, Resource::Texture2d { filterable: true }),
    b(1, 2, Resource::Texture2d { filterable: true }),
    b(1, 3, Resource::Texture2d { filterable: true }),
    b(1, 4, Resource::StorageTexture(CLOUD_FORMAT, 2)),
    b(1, 5, Resource::StorageTexture(CLOUD_FORMAT, 2)),
];

const fn b(group: u32, binding: u32, resource: Resource) -> Binding {
    Binding {
        group,
        binding,
        resource,
    }
}

/// Which pixel of an `n`×`n` cell the `k`-th frame marches: the cells' pixels in the order of
/// a Bayer matrix, so each frame's pixels fall far from the last few frames' and every pixel
/// is marched once in n² frames.
pub fn subset_offset(n: u32, k: u32) -> [u32; 2] {
    let n = n.max(1);
    let want = k % (n * n);
    for y in 0..n {
        for x in 0..n {
            if bayer(x, y, n) == want {
                return [x, y];
            }
        }
    }
    [0, 0]
}

/// Rank of (x, y) in the n×n Bayer matrix (n a power of two): M₂ = [0 2; 3 1] and
/// M₂ₙ(x, y) = 4·M₂(x mod 2, y mod 2) + Mₙ(x div 2, y div 2), so consecutive ranks differ in
/// the coarse position and lie far apart.
fn bayer(x: u32, y: u32, n: u32) -> u32 {
    let m = n.trailing_zeros();
    (0..m)
        .map(|l| {
            let d = [[0, 2], [3, 1]][((y >> l) & 1) as usize][((x >> l) & 1) as usize];
            d * 4u32.pow(m - 1 - l)
        })
        .sum()
}

/// What a reprojected frame was made of: what the next frame moves its pixels by and checks
/// its history against.
#[derive(Clone, Debug)]
pub struct FrameKey {
    pub camera: Camera,
    pub size: (u32, u32),
    pub subset: u32,
    pub map_generation: u64,
    pub time: DateTime<Utc>,
    pub settings: Settings,
}

/// Why the history does not fit the frame, or `None` when it does.
pub fn misfit(last: &FrameKey, now: &FrameKey) -> Option<&'static str> {
    if last.size != now.size || last.subset != now.subset {
        return Some("size");
    }
    if last.map_generation != now.map_generation {
        return Some("map");
    }
    let dt_s = (now.time - last.time).num_milliseconds() as f64 * 1e-3;
    if max_age(dt_s) < MIN_HISTORY_AGE {
        return Some("time");
    }
    let (a, b) = (last.camera.basis(), now.camera.basis());
    let turn = a
        .forward
        .dot(b.forward)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    if a.position.distance(b.position) > TELEPORT_M
        || turn > TELEPORT_TURN_DEG
        || (last.camera.fov_deg - now.camera.fov_deg).abs() > 1e-6
    {
        return Some("teleport");
    }
    if looks_differ(&last.settings, &now.settings) {
        return Some("settings");
    }
    None
}

/// Whether two settings draw different clouds or light (time, drift, frame and exposure aside:
/// those move smoothly, and the exposure is applied after reprojection).
fn looks_differ(a: &Settings, b: &Settings) -> bool {
    a.march != b.march
        || a.layers_on != b.layers_on
        || a.coverage_mul != b.coverage_mul
        || a.density_mul != b.density_mul
        || a.extinction != b.extinction
        || a.hg_g != b.hg_g
        || a.beer_clamp != b.beer_clamp
        || a.visibility_m != b.visibility_m
        || a.sun_override != b.sun_override
}

/// Whether two cameras see the same pixels (a still view): position within 1 mm, the same
/// orientation and field of view.
pub fn same_view(a: &Camera, b: &Camera) -> bool {
    let (p, q) = (a.basis(), b.basis());
    p.position.distance(q.position) < 1e-3
        && p.forward.dot(q.forward) > 1.0 - 1e-12
        && p.view_up.dot(q.view_up) > 1.0 - 1e-12
        && (a.fov_deg - b.fov_deg).abs() < 1e-9
}

/// The subset order's rank this frame marches: the still run's own count (so a still view
/// gathers the cells' pixels from rank 0 up, coarse lattice first), else the running count.
pub fn rank(still: u32, frames: u32) -> u32 {
    if still > 0 {
        still - 1
    } else {
        frames
    }
}

/// How many frames a still view's pixel stays usable when the scene's time moves `dt_s` a frame.
pub fn max_age(dt_s: f64) -> u32 {
    if dt_s.abs() < 1e-3 {
        u32::MAX
    } else {
        (STILL_TIME_S / dt_s.abs()).clamp(1.0, u32::MAX as f64) as u32
    }
}

/// The densest lattice of a still view's own marches after its `k`-th frame (from 0) in an
/// `n`×`n` cell, none older than `max_age` frames: (step, offset). The subset order's ranks
/// b·4ʲ … (b+1)·4ʲ − 1 are the pixels at one offset and every (n / 2ʲ)-th pixel (the Bayer
/// matrix's low digits fix the position's low bits), so the last whole block of 4ʲ ranks is a
/// lattice whose oldest pixel is under 2·4ʲ frames old.
pub fn still_lattice(n: u32, k: u32, max_age: u32) -> (u32, [u32; 2]) {
    let n = n.max(1);
    let mut j = 0;
    while (1u64 << (2 * (j + 1))) <= u64::from(k) + 1
        && (1u64 << (j + 1)) <= u64::from(n)
        && (2u64 << (2 * (j + 1))) <= u64::from(max_age) + 1
    {
        j += 1;
    }
    let block = 1u32 << (2 * j);
    let first = ((k + 1) / block - 1) * block;
    (n >> j, subset_offset(n, first))
}

/// The uniforms that move the last frame's pixels to this camera. `still`: see
/// [`ReprojectParams::still`]; `age`: [`max_age`]; `whole`: the frame before the still run
/// marched every pixel.
pub fn params(
    last: Option<&FrameKey>,
    now: &Camera,
    valid: bool,
    (still, age, whole): (u32, u32, bool),
) -> ReprojectParams {
    let Some(last) = last.filter(|_| valid) else {
        return ReprojectParams::default();
    };
    let n = last.subset;
    let (lattice_step, [lattice_x, lattice_y]) = still_lattice(n, still.saturating_sub(1), age);
    let (a, b) = (last.camera.basis(), now.basis());
    let v = |d: DVec3| [d.x as f32, d.y as f32, d.z as f32];
    let whole = whole && still > 0 && still < age;
    ReprojectParams {
        prev_fwd: v(a.forward),
        prev_tan_half_fov: (last.camera.fov_deg.to_radians() * 0.5).tan() as f32,
        prev_right: v(a.right),
        prev_aspect: (last.size.0 as f64 / last.size.1 as f64) as f32,
        prev_view_up: v(a.view_up),
        valid: 1,
        prev_delta: v(a.position - b.position),
        max_depth_change: MAX_DEPTH_CHANGE,
        still,
        max_age: age,
        lattice_step,
        lattice_x,
        lattice_y,
        whole: u32::from(whole),
        new_weight: still_mean_weight(n, still, age, whole),
        ..ReprojectParams::default()
    }
}

/// The most marches of one pixel a still view averages: `fast` at rest (4×4 cells) takes 256
/// frames to hold 16, 17 s at the CPU window's 15 fps.
pub const STILL_MEAN_MAX: u32 = 16;

/// Which march of its pixel since the camera stopped this frame's is, from 1: one each n²
/// frames in the subset's rank order; after a full march every pixel but rank 0's had one more.
fn still_march(n: u32, still: u32, whole: bool) -> u32 {
    let nn = n.max(1) * n.max(1);
    let k = still.saturating_sub(1);
    k / nn + 1 + u32::from(whole && !k.is_multiple_of(nn))
}

/// The most marches of one pixel a still view's mean spans: [`STILL_MEAN_MAX`], and no more
/// than `max_age` frames hold, so where the scene's time runs it does not lag the weather.
fn still_mean_len(n: u32, max_age: u32) -> u32 {
    (max_age / (n.max(1) * n.max(1))).clamp(1, STILL_MEAN_MAX)
}

/// A still view's weight for the march of a pixel this frame against what its history holds:
/// 1 / m for its m-th march since the camera stopped, so the history holds the mean of its
/// marches at the frames' different jitters. Replaced instead, a still window kept one
/// march's jitter noise and came no closer to the full march after its first n² frames
/// (docs/footprint.md, "A still view's marches averaged"). Over [`still_mean_len`] marches at
/// most.
pub fn still_mean_weight(n: u32, still: u32, max_age: u32, whole: bool) -> f32 {
    1.0 / still_march(n, still, whole).min(still_mean_len(n, max_age)) as f32
}

/// How far across its pixel a still view's marches of it spread ([`still_sample_offset`]):
/// the central half. The window's bilinear enlargement already spreads each march pixel over
/// its neighbours'; marches over the whole pixel blurred twice what the enlargement averages
/// (the made-up deck's ¼ window 0.0118 from the full march after 80 still frames, against
/// 0.0108 over the central half and 0.0102 at the centre alone; docs/footprint.md, "A still
/// view's marches cover their pixels").
pub const STILL_SAMPLE_SPREAD: f32 = 0.5;

/// Where in its pixel a still view's march aims this frame (march pixels from the centre, y
/// down): the m-th march of a pixel at the m-th point of a 16-point Halton (2, 3) set over
/// the pixel's central [`STILL_SAMPLE_SPREAD`], shifted so that its first point, the one march
/// a pixel has until the view has stood n² frames, is the centre. So the mean of a pixel's
/// marches ([`still_mean_weight`]) covers the several view pixels an enlarged march pixel
/// stands for, not the point at its centre alone. The centre wherever a march replaces the
/// last (the mean spans one), lest the picture swim.
pub fn still_sample_offset(n: u32, still: u32, max_age: u32, whole: bool) -> [f32; 2] {
    // A moving view (`still` 0) and each pixel's first march are point 0, the centre.
    if still_mean_len(n, max_age) < 2 {
        return [0.0, 0.0];
    }
    let i = (still_march(n, still, whole) - 1) % STILL_MEAN_MAX;
    let shifted = |base: u32| {
        let (mut x, mut f, mut j) = (0.0f32, 1.0f32, i);
        while j > 0 {
            f /= base as f32;
            x += f * (j % base) as f32;
            j /= base;
        }
        STILL_SAMPLE_SPREAD * ((x + 0.5).fract() - 0.5)
    };
    [shifted(2), shifted(3)]
}

/// The stage's pipelines and its device-lifetime bindings.
pub struct ReprojectPass {
    /// For a moving view, and for a still one ([`ReprojectParams::still`] with a valid
    /// history): reproject.wgsl's `STILL` as a pipeline constant, since a CPU driver runs both
    /// paths for every pixel when the choice is a uniform's (the moving one's cost a still
    /// view, and the still one's about 3 ms of the window's 45 ms frame on lavapipe).
    pipelines: [wgpu::ComputePipeline; 2],
    target_layout: wgpu::BindGroupLayout,
    device_bind: wgpu::BindGroup,
    params: wgpu::Buffer,
}

impl ReprojectPass {
    pub fn new(gpu: &Gpu, uniforms: &wgpu::Buffer) -> ReprojectPass {
        let dev = &gpu.device;
        let stage = wgpu::ShaderStages::COMPUTE;
        let layouts = [0, 1].map(|g| contract::layout(dev, "reproject", BINDINGS, g, stage));
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("reproject"),
            bind_group_layouts: &[Some(&layouts[0]), Some(&layouts[1])],
            immediate_size: 0,
        });
        let module = shader::module(dev, "reproject", shader::REPROJECT);
        let pipelines = [0.0, 1.0].map(|still| {
            super::pipeline::entry_pipeline(
                dev,
                "reproject",
                &layout,
                &module,
                "main",
                &[("STILL", still)],
            )
        });
        let params = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("reproject params"),
            size: std::mem::size_of::<ReprojectParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let sampler = dev.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("history"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        use wgpu::BindingResource as R;
        let device_bind = bind(
            dev,
            "reproject: device",
            &layouts[0],
            [
                R::Buffer(uniforms.as_entire_buffer_binding()),
                R::Buffer(params.as_entire_buffer_binding()),
                R::Sampler(&sampler),
            ],
        );
        let [_, target_layout] = layouts;
        ReprojectPass {
            pipelines,
            target_layout,
            device_bind,
            params,
        }
    }

    /// The bindings that make one history set from the fresh subset and the other set.
    pub fn bind_target(
        &self,
        gpu: &Gpu,
        fresh: [&wgpu::TextureView; 2],
        history: [&wgpu::TextureView; 2],
        out: [&wgpu::TextureView; 2],
    ) -> wgpu::BindGroup {
        use wgpu::BindingResource as R;
        bind(
            &gpu.device,
            "reproject: target",
            &self.target_layout,
            [
                R::TextureView(fresh[0]),
                R::TextureView(fresh[1]),
                R::TextureView(history[0]),
                R::TextureView(history[1]),
                R::TextureView(out[0]),
                R::TextureView(out[1]),
            ],
        )
    }

    pub fn encode(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        params: &ReprojectParams,
        target_bind: &wgpu::BindGroup,
        (width, height): (u32, u32),
        timestamps: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("reproject"),
            timestamp_writes: timestamps,
        });
        let still = params.valid != 0 && params.still != 0;
        pass.set_pipeline(&self.pipelines[usize::from(still)]);
        pass.set_bind_group(0, &self.device_bind, &[]);
        pass.set_bind_group(1, target_bind, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_still_view_averages_its_marches_within_the_age_budget() {
        let paused = max_age(0.0);
        // Each pixel's first march replaces the moving view's history; the m-th weighs 1/m.
        assert_eq!(still_mean_weight(4, 1, paused, false), 1.0);
        assert_eq!(still_mean_weight(4, 16, paused, false), 1.0);
        assert_eq!(still_mean_weight(4, 17, paused, false), 0.5);
        assert_eq!(still_mean_weight(4, 49, paused, false), 0.25);
        assert_eq!(still_mean_weight(4, 100_000, paused, false), 1.0 / 16.0);
        // After a full march every pixel but rank 0's holds one march more.
        assert_eq!(still_mean_weight(4, 2, paused, true), 0.5);
        assert_eq!(still_mean_weight(4, 17, paused, true), 0.5);
        // ×600 at 60 ms a frame (36 s of scene time a frame): replaced, as before the mean.
        assert_eq!(still_mean_weight(4, 1000, max_age(36.0), false), 1.0);
        // ×60 (3.6 s a frame): no more than the 166 frames of the age budget, 10 marches.
        assert_eq!(still_mean_weight(4, 1000, max_age(3.6), false), 0.1);
    }

    #[test]
    fn a_still_views_marches_cover_their_pixel() {
        let paused = max_age(0.0);
        // Moving, or a pixel's first march since the camera stopped: the centre.
        assert_eq!(still_sample_offset(4, 0, paused, false), [0.0, 0.0]);
        for still in 1..=16 {
            assert_eq!(still_sample_offset(4, still, paused, false), [0.0, 0.0]);
        }
        // Where each march replaces the last (×600): the centre, lest the picture swim.
        assert_eq!(still_sample_offset(4, 40, max_age(36.0), false), [0.0, 0.0]);
        // The 16 marches of a pixel: 16 distinct points in its central half, three to five in
        // each quarter of it, their mean near its centre.
        let pts: Vec<[f32; 2]> = (0..16)
            .map(|m| still_sample_offset(4, 16 * m + 5, paused, false))
            .collect();
        let mut quarters = [0; 4];
        for (i, p) in pts.iter().enumerate() {
            let h = 0.5 * STILL_SAMPLE_SPREAD;
            assert!(p.iter().all(|v| (-h..h).contains(v)), "{p:?}");
            assert!(pts[..i].iter().all(|q| q != p), "{p:?} twice");
            quarters[usize::from(p[0] >= 0.0) + 2 * usize::from(p[1] >= 0.0)] += 1;
        }
        assert!(quarters.iter().all(|q| (3..=5).contains(q)), "{quarters:?}");
        let mean = pts
            .iter()
            .fold([0.0; 2], |a, p| [a[0] + p[0] / 16.0, a[1] + p[1] / 16.0]);
        assert!(mean.iter().all(|v| v.abs() < 0.04), "{mean:?}");
        // The 17th begins the set again.
        assert_eq!(still_sample_offset(4, 16 * 16 + 5, paused, false), pts[0]);
    }

    #[test]
    fn every_pixel_of_a_cell_is_marched_once_in_n_squared_frames() {
        for n in [1, 2, 4, 8] {
            let mut seen = vec![false; (n * n) as usize];
            for k in 0..n * n {
                let [x, y] = subset_offset(n, k);
                assert!(x < n && y < n);
                let i = (y * n + x) as usize;
                assert!(!seen[i], "n {n}: ({x}, {y}) twice");
                seen[i] = true;
            }
        }
        // Consecutive frames spread over the cell rather than walking along a row.
        let a = subset_offset(4, 0);
        let b = subset_offset(4, 1);
        let d = (a[0] as i32 - b[0] as i32).abs() + (a[1] as i32 - b[1] as i32).abs();
        assert!(d >= 2, "{a:?} then {b:?}");
    }

    #[test]
    fn a_still_views_lattice_holds_only_marched_pixels_young_enough() {
        for n in [2, 4, 8, 16] {
            for age in [1, 3, 20, u32::MAX] {
                for k in 0..(3 * n * n) {
                    let (step, [ox, oy]) = still_lattice(n, k, age);
                    assert!(step >= 1 && n % step == 0 && ox < step && oy < step);
                    // Every lattice pixel of the cell was marched at one of the last frames,
                    // none older than `age` (or just now).
                    for y in (oy..n).step_by(step as usize) {
                        for x in (ox..n).step_by(step as usize) {
                            let r = bayer(x, y, n);
                            let kk = k % (n * n);
                            assert!(k >= r || r <= kk, "n {n} k {k}: ({x},{y}) never marched");
                            let since = (kk + n * n - r) % (n * n);
                            assert!(
                                since == 0 || since < age,
                                "n {n} k {k} age {age}: ({x},{y}) {since} frames old"
                            );
                        }
                    }
                }
            }
        }
        // Sixteen still frames in a 16×16 cell: the 4-px lattice is whole.
        assert_eq!(still_lattice(16, 15, u32::MAX), (4, [0, 0]));
        assert_eq!(still_lattice(16, 255, u32::MAX), (1, [0, 0]));
        assert_eq!(still_lattice(4, 0, u32::MAX).0, 4);
    }

    fn key(lat: f64, heading: f64) -> FrameKey {
        FrameKey {
            camera: Camera::new(lat, 100.0, 5000.0, heading, 0.0),
            size: (64, 36),
            subset: 4,
            map_generation: 1,
            time: DateTime::<Utc>::default(),
            settings: Settings::new(super::super::Preset::Balanced, DateTime::<Utc>::default()),
        }
    }

    #[test]
    fn history_is_rejected_for_each_reason() {
        let a = key(30.0, 0.0);
        assert_eq!(misfit(&a, &a), None);
        let mut b = a.clone();
        b.camera = Camera::new(30.005, 100.0, 5000.0, 1.0, 0.0);
        assert_eq!(
            misfit(&a, &b),
            None,
            "a small step and turn keep the history"
        );
        assert_eq!(misfit(&a, &key(31.0, 0.0)), Some("teleport"));
        assert_eq!(misfit(&a, &key(30.0, 45.0)), Some("teleport"));
        let mut c = a.clone();
        c.map_generation = 2;
        assert_eq!(misfit(&a, &c), Some("map"));
        let mut d = a.clone();
        d.time = a.time + chrono::Duration::hours(1);
        assert_eq!(misfit(&a, &d), Some("time"));
        // A time-lapse's 10 min a frame, and the window's ×600 under 7 fps, keep no history;
        // ×600 at 10 fps (60 s a frame) keeps it.
        d.time = a.time + chrono::Duration::minutes(10);
        assert_eq!(misfit(&a, &d), Some("time"));
        d.time = a.time - chrono::Duration::seconds(90);
        assert_eq!(misfit(&a, &d), Some("time"));
        d.time = a.time + chrono::Duration::seconds(60);
        assert_eq!(misfit(&a, &d), None);
        let mut e = a.clone();
        e.settings.coverage_mul = 1.5;
        assert_eq!(misfit(&a, &e), Some("settings"));
        let mut f = a.clone();
        f.size = (128, 72);
        assert_eq!(misfit(&a, &f), Some("size"));
        let mut g = a.clone();
        g.settings.frame_index = 7;
        g.settings.exposure_ev = 1.0;
        assert_eq!(
            misfit(&a, &g),
            None,
            "frame index and exposure do not count"
        );
    }
}
