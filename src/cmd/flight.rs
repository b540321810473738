//! `stratus flight`: a keyframed path rendered headless to a PNG sequence (and MP4 with ffmpeg),
//! or with `--follow` a simulator's session: a frame every 1/fps s of wall time from the
//! follower's pose for `--duration` s. While the simulator is silent the frames hold its last
//! pose: the run says so when the silence starts and counts those frames at the end (exit 0:
//! the recording is complete, only its content is frozen; docs/fly.md).
//!
//! What the output folder holds afterwards (docs/files.md):
//! - Before anything is rendered, the frame count and the disk it needs are checked against
//!   `--max-frames` and the folder's free space.
//! - Frames are rendered into a hidden staging folder inside the output folder, and only moved
//!   to `frame-NNNNN.png` when every frame (and the MP4) is done. A run that fails or is
//!   interrupted leaves the folder as it was (and removes the folder if it created it).
//! - After a success the folder holds exactly this run's frames: `frame-NNNNN.png` files of an
//!   earlier, longer run are removed; no other file is touched.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::{Duration, Instant};

use anyhow::Context;
use chrono::{DateTime, Utc};
use stratus_ingest::cloudmap::CloudMap;
use stratus_ingest::error::shown;
use stratus_ingest::output::{
    commit_staged_then, remove_if_empty, StagingDir, FRAMES_STAGING_PREFIX,
};
use stratus_ingest::region::parse_size;

use stratus::flight::{FlightPath, DEFAULT_MAX_FRAMES};
use stratus::follow::{Fix, Follower, Source, KNOT, STALE_AFTER};
use stratus::picture::save_png;
use stratus::render::{Camera, Renderer, Settings, View};
use stratus::scene::Scene;

use super::files::{check_out, create_folder};
use super::options::{camera, progress_bar, LookOpts, EYE_HEIGHT_M};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// CloudMap sidecar (MAP.json).
    #[arg(long)]
    pub map: PathBuf,
    /// Keyframed path (JSON; see docs/fly.md).
    #[arg(long, required_unless_present = "follow", conflicts_with = "follow")]
    pub path: Option<PathBuf>,
    /// Record a simulator's session instead: xplane[:PORT] (49003) or flightgear[:PORT] (5505).
    #[arg(long, requires = "duration")]
    pub follow: Option<String>,
    /// Seconds of wall time to record with --follow.
    #[arg(long, requires = "follow")]
    pub duration: Option<f64>,
    /// Seconds --follow waits for the simulator's first packet.
    #[arg(long, default_value_t = 10.0, requires = "follow")]
    pub wait: f64,
    /// Vertical field of view with --follow, degrees.
    #[arg(long, default_value_t = 60.0, requires = "follow")]
    pub fov: f64,
    /// Output directory for frame-NNNNN.png (and flight.mp4 when ffmpeg is present).
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value = "640x360")]
    pub size: String,
    /// Frames per second of path time (with --follow: of wall time).
    #[arg(long, default_value_t = 10.0)]
    pub fps: f64,
    /// Refuse a path that makes more frames than this (checked before anything is rendered).
    #[arg(long, default_value_t = DEFAULT_MAX_FRAMES,
          value_parser = clap::value_parser!(u64).range(1..))]
    pub max_frames: u64,
    /// Temporal reprojection: each frame marches one pixel of each subset cell (the preset's
    /// size) and reprojects the rest from the frame before (a frame whose history does not
    /// fit, the first or after a jump, marches every pixel): on or off.
    #[arg(long, default_value = "on", action = clap::ArgAction::Set, value_parser = super::fly::parse_on_off)]
    pub reprojection: bool,
    #[command(flatten)]
    pub look: LookOpts,
}

/// Disk a frame is assumed to take per pixel: RGBA8 PNG frames measured 0.3–0.7 bytes a pixel
/// at 640×360, so 1 byte is an estimate with room, not a bound (a frame could take up to 4).
const FRAME_BYTES_PER_PIXEL: f64 = 1.0;

/// The MP4 ffmpeg makes of the frames.
const MP4: &str = "flight.mp4";

fn frame_name(i: u64) -> String {
    format!("frame-{i:05}.png")
}

/// The frame number of a name this command writes (`frame-00042.png`), exactly as it writes
/// it; anything else is not ours.
fn frame_number(name: &OsStr) -> Option<u64> {
    let n: u64 = name
        .to_str()?
        .strip_prefix("frame-")?
        .strip_suffix(".png")?
        .parse()
        .ok()?;
    (name.to_str() == Some(frame_name(n).as_str())).then_some(n)
}

pub fn run(a: Args) -> anyhow::Result<ExitCode> {
    // Everything that can be checked without rendering, before anything is created.
    if !(a.fps > 0.0 && a.fps <= 240.0) {
        anyhow::bail!("--fps {} must be in (0, 240]", a.fps);
    }
    let (w, h) = parse_size(&a.size)?;
    let scene = Scene::open(&a.map);
    let mut inputs = scene.files();
    let (mut source, n) = match (&a.path, &a.follow) {
        (Some(file), _) => {
            let path = FlightPath::load(file)?;
            let n = path
                .frames(a.fps, a.max_frames)
                .map_err(|e| anyhow::anyhow!("{}: {e}", shown(file)))?;
            inputs.push(file.clone());
            (Cameras::Path(path), n)
        }
        (None, Some(follow)) => {
            let n = follow_frames(a.duration.unwrap_or(0.0), a.fps, a.max_frames)?;
            (Cameras::Follow(Box::new(follow_setup(&a, follow)?)), n)
        }
        (None, None) => anyhow::bail!("--path or --follow is required"),
    };
    check_folder(&a.out, &inputs, n)?;
    check_space(&a.out, n, w, h)?;
    // A series: the GPU holds the two steps around each frame's time and blends them.
    let (map, timeline) = scene.for_renderer(a.look.moment()?)?;
    let mut settings = a.look.settings(&map, &a.map)?;
    if a.reprojection {
        settings.reprojection = stratus::render::Reprojection::On { full_reset: true };
    }
    if let Cameras::Follow(f) = &mut source {
        // Before anything is created: a simulator that never speaks leaves no trace.
        f.wait_first(a.wait)?;
    }

    let created = create_folder(&a.out)?;
    let result = render_and_commit(&a, &mut source, n, (w, h), (&map, timeline), &settings);
    if result.is_err() {
        // A folder this run created goes too (it is empty: the staging folder is gone).
        remove_if_empty(&created);
    }
    let (removed, mp4, lifted) = result?;
    if let Some(line) = lifted.line(n) {
        eprintln!("{line}");
    }
    let last = n - 1;
    let frames = if n == 1 {
        format!("1 frame {}", frame_name(0))
    } else {
        format!("{n} frames frame-{:05}..{last:05}.png", 0)
    };
    let earlier = if removed > 0 {
        format!("; removed {removed} frame(s) of an earlier, longer run")
    } else {
        String::new()
    };
    out!("wrote {frames} to {}{earlier}", shown(&a.out))?;
    if let Cameras::Follow(f) = &mut source {
        let st = f.follower.status(Instant::now());
        out!(
            "{}: {} packets, {} malformed (ignored); {} of {n} frames held its last pose",
            st.kind.name(),
            st.received,
            st.malformed,
            f.held
        )?;
        if let Some(line) = f.speed_line() {
            out!("{line}")?;
        }
        if let Some(line) = f.held_line(n) {
            eprintln!("{line}");
        }
    }
    match mp4 {
        Mp4::Made => out!("{}", shown(&a.out.join(MP4)))?,
        Mp4::Failed => {
            eprintln!("ffmpeg failed; the PNG frames are complete (no {MP4} written)")
        }
        Mp4::NoFfmpeg => out!("(ffmpeg not found: PNG frames only)")?,
    }
    Ok(ExitCode::SUCCESS)
}

/// The output folder must be a folder (or absent), and the names this run writes there
/// absent or regular files that are none of the inputs.
fn check_folder(out: &Path, inputs: &[PathBuf], n: u64) -> anyhow::Result<()> {
    match std::fs::metadata(out) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => anyhow::bail!("{}: --out must be a folder; it is a file", shown(out)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => anyhow::bail!("{}: cannot use as the output folder: {e}", shown(out)),
    }
    for i in 0..n {
        check_out(&out.join(frame_name(i)), inputs)?;
    }
    check_out(&out.join(MP4), inputs)?;
    // Frames of an earlier run are removed after a success: none may be an input either.
    for e in std::fs::read_dir(out).with_context(|| format!("{}: cannot list", shown(out)))? {
        let e = e.with_context(|| format!("{}: cannot list", shown(out)))?;
        if frame_number(&e.file_name()).is_some() {
            check_out(&e.path(), inputs)?;
        }
    }
    Ok(())
}

/// Refuse a run whose frames would not fit on the output folder's file system (estimated with
/// [`FRAME_BYTES_PER_PIXEL`]), before any is rendered.
fn check_space(out: &Path, n: u64, w: u32, h: u32) -> anyhow::Result<()> {
    let need = n as f64 * w as f64 * h as f64 * FRAME_BYTES_PER_PIXEL;
    let Some(free) = free_bytes(out) else {
        return Ok(());
    };
    if need > free as f64 {
        anyhow::bail!(
            "{}: {n} frames of {w}x{h} need about {:.1} MiB; the file system has {:.1} MiB free (fewer frames, a lower --fps or a smaller --size)",
            shown(out),
            need / (1 << 20) as f64,
            free as f64 / (1 << 20) as f64
        );
    }
    Ok(())
}

/// Free bytes on the file system `path` is (or would be created) on, where the OS says.
fn free_bytes(path: &Path) -> Option<u64> {
    let existing = path.ancestors().find(|p| {
        let p = if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        };
        p.exists()
    })?;
    let existing = if existing.as_os_str().is_empty() {
        Path::new(".")
    } else {
        existing
    };
    stratus_ingest::fetch::space::free_bytes(existing)
}

enum Mp4 {
    Made,
    Failed,
    NoFfmpeg,
}

/// Render every frame into a staging folder inside `out`, make the MP4 there, then move them
/// into place and remove frames of an earlier run beyond this one's. Returns how many of
/// those were removed.
fn render_and_commit(
    a: &Args,
    source: &mut Cameras,
    n: u64,
    (w, h): (u32, u32),
    (map, mut timeline): (&CloudMap, Option<stratus::timeline::Timeline>),
    settings: &Settings,
) -> anyhow::Result<(usize, Mp4, Lifted)> {
    // Stale staging folders of a killed run are swept as this one is made.
    let staging = StagingDir::create_in(&a.out, FRAMES_STAGING_PREFIX)?;
    let mut r = Renderer::new(a.look.gpu()?, map);
    if let Cameras::Follow(f) = &mut *source {
        // The first frames pay for what the renderer builds on first use (tens of seconds on a
        // CPU driver): paid here, before the recording's clock starts, or frame 1 would come
        // that much after frame 0 and the frames after it in a burst. At another size than
        // the frames', so frame 0 shares no history with these and is marched whole.
        let cam = f.camera_now();
        let size = if (w, h) == (8, 8) { 16 } else { 8 };
        for i in 0..2 {
            let s = frame_settings(&mut r, settings, None, &mut timeline, i)?;
            r.render(&View::Perspective(cam), size, size, &s)?;
        }
    }
    let pb = progress_bar(n, "frames");
    let mut lifted = Lifted::default();
    for i in 0..n {
        let (mut cam, time) = source.at(i, a.fps);
        if let Cameras::Follow(f) = &mut *source {
            if let Some(note) = f.note.take() {
                pb.suspend(|| eprintln!("{note}"));
            }
        }
        lifted.lift(i, &mut cam, map);
        let s = frame_settings(&mut r, settings, time, &mut timeline, i)?;
        let frame = r.render(&View::Perspective(cam), w, h, &s)?;
        save_png(&staging.path().join(frame_name(i)), &frame.to_image())?;
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mp4 = make_mp4(staging.path(), a.fps);

    // Every frame and the MP4 in place as one set (checked again first: something may have
    // appeared under these names while we rendered), then the frames of an earlier, longer run
    // removed, all under the commit lock.
    let mut files: Vec<(PathBuf, PathBuf)> = (0..n)
        .map(|i| {
            (
                staging.path().join(frame_name(i)),
                a.out.join(frame_name(i)),
            )
        })
        .collect();
    if matches!(mp4, Mp4::Made) {
        files.push((staging.path().join(MP4), a.out.join(MP4)));
    }
    let removed = commit_staged_then(&files, &a.out.join(MP4), || earlier_frames(&a.out, n))??;
    Ok((removed, mp4, lifted))
}

/// Remove the frames of an earlier run numbered `n` or more (only regular files named exactly
/// as this command names frames); returns how many.
fn earlier_frames(out: &Path, n: u64) -> anyhow::Result<usize> {
    let mut removed = 0;
    for e in std::fs::read_dir(out)
        .with_context(|| format!("{}: cannot list", shown(out)))?
        .flatten()
    {
        let is_file = e.file_type().is_ok_and(|t| t.is_file());
        if is_file
            && frame_number(&e.file_name()).is_some_and(|k| k >= n)
            && std::fs::remove_file(e.path()).is_ok()
        {
            removed += 1;
        }
    }
    Ok(removed)
}

/// Frame `i`'s settings: the path's time where it keys one, and a series' steps around it
/// made ready on the GPU.
fn frame_settings(
    r: &mut Renderer,
    settings: &Settings,
    time: Option<DateTime<Utc>>,
    timeline: &mut Option<stratus::timeline::Timeline>,
    i: u64,
) -> anyhow::Result<Settings> {
    let mut s = settings.clone();
    if let Some(t) = time {
        s.time = t;
    }
    if let Some(tl) = timeline {
        s.drift_m = tl.prepare(r, s.time)?;
        s.streak_wind = Some(tl.streak_wind());
    }
    s.frame_index = i as u32;
    Ok(s)
}

/// Frames whose camera the path (or the simulator) put below the map's terrain: each is
/// lifted to [`EYE_HEIGHT_M`] above it and rendered, and the run says so in one line. A path
/// keyed over the old flat sea-level ground, or an aircraft on a runway lower than the
/// forecast's smooth 2.5° terrain, still renders, as a simulator's terrain-following camera
/// would, instead of failing after minutes of frames.
#[derive(Debug, Default)]
struct Lifted {
    frames: u64,
    /// The first lifted frame: index, position, its altitude and the ground's.
    first: Option<(u64, f64, f64, f64, f64)>,
}

impl Lifted {
    fn lift(&mut self, i: u64, cam: &mut Camera, map: &CloudMap) {
        let (ground, _) = map.ground_height_m(cam.lat_deg, cam.lon_deg);
        if cam.alt_m >= ground {
            return;
        }
        self.frames += 1;
        self.first
            .get_or_insert((i, cam.lat_deg, cam.lon_deg, cam.alt_m, ground));
        cam.alt_m = ground + EYE_HEIGHT_M;
    }

    /// The warning line, when any frame was lifted.
    fn line(&self, n: u64) -> Option<String> {
        let (i, lat, lon, alt, ground) = self.first?;
        Some(format!(
            "warning: {} of {n} frames were below the terrain and were rendered {EYE_HEIGHT_M} m above it instead (first: frame {i} at {lat:.3},{lon:.3}, {alt:.0} m under ground at {ground:.0} m)",
            self.frames
        ))
    }
}

/// Where each frame's camera comes from.
enum Cameras {
    Path(FlightPath),
    Follow(Box<Following>),
}

impl Cameras {
    /// Frame `i`'s camera and (for a keyed path) time.
    fn at(&mut self, i: u64, fps: f64) -> (Camera, Option<DateTime<Utc>>) {
        match self {
            Cameras::Path(p) => p.at(p.keys[0].t + i as f64 / fps),
            Cameras::Follow(f) => (f.at(i, fps), None),
        }
    }
}

/// A simulator being recorded: the follower, the wall clock the frames keep to, and what the
/// frames were rendered from.
struct Following {
    follower: Follower,
    fov: f64,
    /// When frame 0 was taken; frame i is due i/fps s later.
    start: Option<Instant>,
    /// Frames taken more than [`STALE_AFTER`] after the last packet (their pose is held), and
    /// the first of them.
    held: u64,
    first_held: Option<u64>,
    /// The last frame was held.
    silent: bool,
    /// The ground speed each frame with a known one was rendered at (m/s), and whether the
    /// last was the simulator's own.
    speeds: Vec<f64>,
    reported: bool,
    /// A line to print (above the progress bar) when a silence starts or ends.
    note: Option<String>,
}

/// Longest --wait for the first packet: an hour.
const MAX_WAIT_S: f64 = 3600.0;

/// Frames a recording of `duration` s at `fps` makes (one every 1/fps s, the first at 0),
/// refused above `max` before anything is bound or rendered.
fn follow_frames(duration: f64, fps: f64, max: u64) -> anyhow::Result<u64> {
    if !(duration.is_finite() && duration > 0.0) {
        anyhow::bail!("--duration {duration} must be a positive number of seconds");
    }
    let frames = (duration * fps).ceil().max(1.0);
    if frames > max as f64 {
        anyhow::bail!(
            "{duration} s at {fps} fps is {frames} frames, more than the limit of {max} (raise it with --max-frames)"
        );
    }
    Ok(frames as u64)
}

fn follow_setup(a: &Args, follow: &str) -> anyhow::Result<Following> {
    if !(a.wait.is_finite() && a.wait > 0.0 && a.wait <= MAX_WAIT_S) {
        anyhow::bail!("--wait {} must be in (0, {MAX_WAIT_S}] seconds", a.wait);
    }
    // The same check the renderer makes, before a socket is bound.
    camera(0.0, 0.0, 1000.0, 0.0, 0.0, a.fov)?;
    let source: Source = follow.parse()?;
    Ok(Following {
        follower: Follower::bind(source)?,
        fov: a.fov,
        start: None,
        held: 0,
        first_held: None,
        silent: false,
        speeds: Vec::new(),
        reported: false,
        note: None,
    })
}

impl Following {
    /// Wait up to `seconds` for the first good packet.
    fn wait_first(&mut self, seconds: f64) -> anyhow::Result<()> {
        let source = self.follower.source();
        eprintln!(
            "waiting up to {seconds} s (--wait) for {} on UDP port {}: {}",
            source.kind.name(),
            source.port,
            source.setup_hint()
        );
        let until = Instant::now() + Duration::from_secs_f64(seconds);
        loop {
            self.follower.poll(Instant::now());
            if self.follower.last_fix().is_some() {
                return Ok(());
            }
            if Instant::now() >= until {
                let st = self.follower.status(Instant::now());
                anyhow::bail!(
                    "no packet from {} on UDP port {} in {seconds} s ({} malformed); is its output sent to this machine and port? Nothing was written",
                    st.kind.name(),
                    st.port,
                    st.malformed
                );
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// The camera for frame `i`: wait until it is due (a slow renderer makes it late, never
    /// early), read what has arrived, and take the pose now.
    fn at(&mut self, i: u64, fps: f64) -> Camera {
        let start = *self.start.get_or_insert_with(Instant::now);
        let due = start + Duration::from_secs_f64(i as f64 / fps);
        let now = Instant::now();
        if due > now {
            std::thread::sleep(due - now);
        }
        let now = Instant::now();
        self.follower.poll(now);
        self.note_silence(i, now);
        let fix = self.fix(now);
        // For scripts/flightgear-check.sh: what each frame was rendered from, on the wall clock
        // a packet logger beside the simulator keeps (RUST_LOG=stratus::follow=debug).
        let unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        tracing::debug!(
            target: "stratus::follow::frames",
            "frame {i} unix {unix:.3} lat {:.7} lon {:.7} alt {:.1} heading {:.2} pitch {:.2} roll {:.2} held {}",
            fix.lat,
            fix.lon,
            fix.alt_m,
            fix.heading,
            fix.pitch,
            fix.roll,
            self.silent
        );
        self.camera(&fix)
    }

    /// The camera at the aircraft's pose now (what has arrived read first), for the warm-up.
    fn camera_now(&mut self) -> Camera {
        let now = Instant::now();
        self.follower.poll(now);
        let fix = self.fix(now);
        self.camera(&fix)
    }

    fn camera(&self, fix: &Fix) -> Camera {
        let mut cam = fix.camera();
        cam.fov_deg = self.fov;
        cam
    }

    /// The pose at `now`.
    fn fix(&self, now: Instant) -> Fix {
        // wait_first saw a packet, so there is a pose; the fallback is never used.
        self.follower.pose(now).unwrap_or(Fix {
            lat: 0.0,
            lon: 0.0,
            alt_m: 1000.0,
            heading: 0.0,
            pitch: 0.0,
            roll: 0.0,
            ground_speed: None,
            climb: None,
        })
    }
}

impl Following {
    /// Count frame `i` as held when no packet came for over [`STALE_AFTER`], note when a
    /// silence starts or ends, and log the speed a live frame is rendered at.
    fn note_silence(&mut self, i: u64, now: Instant) {
        let st = self.follower.status(now);
        let held = st.stale_s.is_some();
        let name = st.kind.name();
        if held {
            self.held += 1;
            self.first_held.get_or_insert(i);
            if !self.silent {
                self.note = Some(format!(
                    "warning: no packet from {name} for {:.1} s at frame {i}: the frames hold its last pose until packets come back",
                    st.stale_s.unwrap_or(0.0)
                ));
            }
        } else {
            if self.silent {
                self.note = Some(format!("{name}'s packets are back at frame {i}"));
            }
            if let Some(v) = self.follower.velocity() {
                self.speeds.push(v.ground);
                self.reported = v.reported;
            }
        }
        self.silent = held;
    }

    /// The ground speeds the live frames were rendered at.
    fn speed_line(&self) -> Option<String> {
        let n = self.speeds.len();
        let lo = self.speeds.iter().copied().reduce(f64::min)?;
        let hi = self.speeds.iter().copied().reduce(f64::max)?;
        let mean = self.speeds.iter().sum::<f64>() / n as f64;
        let from = if self.reported {
            "the simulator's own"
        } else {
            "measured from packet arrival times"
        };
        Some(format!(
            "ground speed over {n} frames: {lo:.1}-{hi:.1} m/s ({:.0}-{:.0} kt), mean {mean:.1} m/s ({from})",
            lo / KNOT,
            hi / KNOT
        ))
    }

    /// The warning at the end when any frame held the last pose.
    fn held_line(&self, n: u64) -> Option<String> {
        let first = self.first_held?;
        Some(format!(
            "warning: {} of {n} frames hold {}'s last pose: no packet had come for over {} s (first: frame {first}); the recording is complete, the simulator was silent",
            self.held,
            self.follower.source().kind.name(),
            STALE_AFTER.as_secs_f64()
        ))
    }
}

/// `flight.mp4` in `dir` from its frames, when ffmpeg is installed.
fn make_mp4(dir: &Path, fps: f64) -> Mp4 {
    let ffmpeg = Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ffmpeg {
        return Mp4::NoFfmpeg;
    }
    let status = Command::new("ffmpeg")
        .args([
            "-y",
            "-loglevel",
            "error",
            "-framerate",
            &fps.to_string(),
            "-i",
        ])
        .arg(dir.join("frame-%05d.png"))
        .args([
            "-pix_fmt",
            "yuv420p",
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
        ])
        .arg(dir.join(MP4))
        .status();
    if status.is_ok_and(|s| s.success()) {
        Mp4::Made
    } else {
        Mp4::Failed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_our_frame_names_are_ours() {
        assert_eq!(frame_number(OsStr::new("frame-00042.png")), Some(42));
        assert_eq!(frame_number(OsStr::new("frame-123456.png")), Some(123456));
        for theirs in [
            "frame-42.png",
            "frame-000042.png",
            "frame-00042.png.bak",
            "my-frame-00042.png",
            "frame-0004a.png",
            "frame-+0042.png",
            "flight.mp4",
        ] {
            assert_eq!(frame_number(OsStr::new(theirs)), None, "{theirs}");
        }
    }
}
