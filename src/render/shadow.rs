//! Shadow stage: dispatches shaders/shadow.wgsl, the full-column light (DESIGN §8). A volume
//! over the map's region (uv × altitude) holds, per texel, the cloud's mean optical depth from
//! there to the top of the cloud toward the key light and straight up. The march lights its
//! samples with it beyond the short light march, its ambient sees the sky through it, and the
//! ground takes the clouds' shadows from it. It is made again only when the key light moves,
//! the map changes or the look does, never for the camera alone; after a key-light move it is
//! made a slice a frame into a second volume while the first lights the frames ([`SLICES`]).
//!
//! Each volume is shown through its own scene group (render::scene, which owns that group's
//! other resources): the march, present and exposure stages read the front one's.

use super::contract::{self, Binding, Resource};
use super::frame::{flags, FrameUniforms};
use super::gpu::Gpu;
use super::march::{MarchPass, GROUP_TARGET};
use super::pipeline::{bind, StagePipelines, Variant};
pub use super::scene::ShadowParams;
use super::scene::{params_buffer, Scene};
use super::shader;
use super::texture::texture_3d;
use stratus_ingest::region::Region;

pub const VOLUME_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
/// Texels along the region's longer side (the other side in proportion, in kilometres).
pub const MAX_SIDE: u32 = 128;
/// Altitude levels.
pub const LEVELS: u32 = 32;
/// Samples per path toward the key light and per column.
pub const STEPS: u32 = 32;
/// A low Sun's path is cut here: beyond it a 16 km deep shell is crossed at under 2°.
pub const MAX_PATH_M: f32 = 600_000.0;
/// The key light may move this far (degrees) before the volume is made again.
pub const REBUILD_DEG: f64 = 0.25;
/// A volume made again because the key light moved is made over this many frames, a slice of
/// rows each, into the second volume while the first still lights the frame; then they swap.
/// A moving Sun so costs a frame 1/8 of a volume rather than a whole one (0.6 s on lavapipe),
/// and the light lags the Sun by at most 8 frames. A changed cloud (map, look) is made whole at
/// once: the old volume would light the wrong cloud.
pub const SLICES: u32 = 8;

/// shadow.wgsl's own bindings (groups 0 and 1 are the march's).
pub const OWN_BINDINGS: &[Binding] = &[
    Binding {
        group: GROUP_TARGET,
        binding: 0,
        resource: Resource::StorageTexture(VOLUME_FORMAT, 3),
    },
    contract::params(GROUP_TARGET, 1),
];

/// Every binding of shadow.wgsl.
pub fn bindings() -> Vec<Binding> {
    super::march::BINDINGS
        .iter()
        .filter(|b| b.group != GROUP_TARGET)
        .chain(OWN_BINDINGS)
        .copied()
        .collect()
}

/// Volume size for a region: [`MAX_SIDE`] along its longer side in kilometres.
pub fn volume_size(region: &Region) -> (u32, u32, u32) {
    let (lat, _) = region.centre();
    let wide = region.lon_span() * lat.to_radians().cos().max(0.05);
    let tall = (region.north - region.south).max(1e-6);
    let side = |a: f64, b: f64| ((MAX_SIDE as f64 * (a / b).min(1.0)).round() as u32).max(8);
    (side(wide, tall), side(tall, wide), LEVELS)
}

/// The direction of the light the volume is made for: the Sun, or the Moon when it is the key.
fn key_light(u: &FrameUniforms) -> [f32; 3] {
    if u.sun_is_key != 0 {
        u.sun_dir
    } else {
        u.moon_dir
    }
}

/// What the volume depends on: it is made again when any of these change.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Inputs {
    key_dir: [f32; 3],
    look: [f32; 25],
    flags: u32,
    map_generation: u64,
}

impl Inputs {
    fn of(u: &FrameUniforms, key_dir: [f32; 3], map_generation: u64) -> Inputs {
        let mut look = [0.0; 25];
        let vals = [
            // Between two forecast steps the blend moves the cloud: again every 2 % of the way.
            (u.blend_w * 50.0).round() / 50.0,
            u.region_south,
            u.region_north,
            u.region_west,
            u.region_lon_span,
            u.shell_base_m,
            u.shell_top_m,
            u.coverage_mul,
            u.density_mul,
            u.extinction,
            u.tower_base_m,
            u.tower_top_m,
            u.st_scale[0],
            u.st_scale[1],
            u.st_offset[0],
            u.st_offset[1],
        ]
        .into_iter()
        .chain(u.layer_base)
        .chain(u.layer_top)
        .chain(u.layer_scale);
        for (l, v) in look.iter_mut().zip(vals) {
            *l = v;
        }
        // Only the flags that change the cloud itself.
        let shape = flags::STRUCTURE | flags::TOWERS | flags::STREAKS | flags::CELLS | flags::CULL;
        Inputs {
            key_dir,
            look,
            flags: u.flags & shape,
            map_generation,
        }
    }

    fn needs_rebuild(&self, last: &Inputs) -> bool {
        let d = |a: [f32; 3]| glam::Vec3::from(a);
        let moved = d(self.key_dir).dot(d(last.key_dir)) < (REBUILD_DEG.to_radians().cos() as f32);
        moved || !self.same_cloud(last)
    }

    /// Whether the cloud itself is the one `last` was made of (only the key light may differ).
    fn same_cloud(&self, last: &Inputs) -> bool {
        self.look == last.look
            && self.flags == last.flags
            && self.map_generation == last.map_generation
    }
}

/// One volume with the bind groups that make it and look it up.
struct Volume {
    _texture: wgpu::Texture,
    /// The shadow stage writing it (with the build's parameters).
    own_bind: wgpu::BindGroup,
    /// The scene group reading it (with the look-up parameters).
    scene_bind: wgpu::BindGroup,
}

/// A volume being made over several frames into the volume that is not shown.
#[derive(Clone, Copy, Debug)]
struct Build {
    inputs: Inputs,
    key_dir: [f32; 3],
    next_row: u32,
}

pub struct ShadowPass {
    pipelines: StagePipelines,
    own_layout: wgpu::BindGroupLayout,
    /// The scene group's other resources (render::scene).
    scene: Scene,
    /// What the shadow stage making a volume reads (its key light and rows).
    build_params: wgpu::Buffer,
    size: (u32, u32, u32),
    /// The volume that lights the frames (`front`) and the one the next is made in (two).
    volumes: Vec<Volume>,
    front: usize,
    /// What the front volume was made for; `None`: it must be made whole before use.
    last: Option<Inputs>,
    building: Option<Build>,
    /// Volumes finished so far (a test checks a camera move makes none).
    pub builds: u32,
}

impl ShadowPass {
    pub fn new(gpu: &Gpu, march: &MarchPass, scene: Scene, region: &Region) -> ShadowPass {
        let (pipelines, own_layout) = super::pipeline::cloud_stage(
            gpu,
            "shadow",
            march.shared_layouts(),
            (OWN_BINDINGS, GROUP_TARGET, shader::SHADOW),
            &[("MEAN_DENSITY", 1.0)],
            // The light volume takes no detail noise and draws no view.
            flags::DETAIL | flags::NO_SKY | flags::GRAZE,
        );
        let mut pass = ShadowPass {
            pipelines,
            own_layout,
            scene,
            build_params: params_buffer(gpu, "shadow build params"),
            size: volume_size(region),
            volumes: Vec::new(),
            front: 0,
            last: None,
            building: None,
            builds: 0,
        };
        pass.rebind(gpu);
        pass
    }

    fn make_volume(&self, gpu: &Gpu) -> Volume {
        let dev = &gpu.device;
        let texture = texture_3d(
            dev,
            "shadow volume",
            self.size,
            VOLUME_FORMAT,
            wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let view = texture.create_view(&Default::default());
        use wgpu::BindingResource as R;
        let own_bind = bind(
            dev,
            "shadow: own",
            &self.own_layout,
            [
                R::TextureView(&view),
                R::Buffer(self.build_params.as_entire_buffer_binding()),
            ],
        );
        Volume {
            _texture: texture,
            own_bind,
            scene_bind: self.scene.bind(gpu, &view),
        }
    }

    /// A new map's region: a volume of its size (the old one when the size is the same).
    pub fn set_region(&mut self, gpu: &Gpu, region: &Region) {
        let size = volume_size(region);
        if size != self.size {
            self.size = size;
            self.rebind(gpu);
        }
        self.invalidate();
    }

    /// A map's ground (or none: sea level and a plain albedo).
    pub fn set_ground(&mut self, gpu: &Gpu, ground: Option<&stratus_ingest::ground::Ground>) {
        self.scene.set_ground(gpu, ground);
        self.rebind(gpu);
    }

    fn rebind(&mut self, gpu: &Gpu) {
        self.volumes = vec![self.make_volume(gpu), self.make_volume(gpu)];
        self.invalidate();
    }

    /// Forget what the volume was made for: the next update makes it again, whole.
    pub fn invalidate(&mut self) {
        self.last = None;
        self.building = None;
    }

    /// Make the next update light the frame with a volume made for exactly its key light and
    /// cloud: kept if the front one is, else made whole at once. A single picture is then lit
    /// by its own light, not by the volume of the last picture drawn, within [`REBUILD_DEG`]
    /// of it or [`SLICES`] frames from being replaced (the footprint bench's noon view after
    /// the same camera at dusk: RMSE against its twin 0.0127 lit so, 0.0131 by its own light).
    pub fn require_exact(&mut self, u: &FrameUniforms, map_generation: u64) {
        let key_dir = key_light(u);
        if self.last == Some(Inputs::of(u, key_dir, map_generation)) {
            self.building = None;
        } else {
            self.invalidate();
        }
    }

    pub fn scene_bind(&self) -> &wgpu::BindGroup {
        &self.volumes[self.front].scene_bind
    }

    /// Make the volume for this frame's uniforms (already written to the march's uniform
    /// buffer before `enc` runs) if what it depends on changed; `enabled` is the preset's
    /// switch. A changed cloud makes it whole now; a moved key light starts (or goes on with)
    /// a volume made [`SLICES`] rows at a time into the other volume, shown when done.
    /// Returns whether a volume was finished.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        march: &MarchPass,
        map_bind: &wgpu::BindGroup,
        u: &FrameUniforms,
        switches: (bool, bool, bool),
        map_generation: u64,
    ) -> bool {
        let key_dir = key_light(u);
        let inputs = Inputs::of(u, key_dir, map_generation);
        let params = self.look_up(u, key_dir, switches);
        // The ground's part can change without the volume (the preset's terrain switch).
        self.scene.write_params(gpu, &params);
        let Some((target, build)) = self.next_build(inputs, key_dir) else {
            // Settled: nothing to make.
            return false;
        };
        if params.enabled == 0 {
            // Look-ups give no cloud; switched on again, it is made whole.
            self.invalidate();
            return false;
        }
        let rows = self.size.1;
        let row_end = if target == self.front {
            rows
        } else {
            (build.next_row + rows.div_ceil(SLICES)).min(rows)
        };
        let build_params = ShadowParams {
            key_dir: build.key_dir,
            row0: build.next_row,
            row_end,
            ..params
        };
        gpu.queue
            .write_buffer(&self.build_params, 0, bytemuck::bytes_of(&build_params));
        self.dispatch(
            gpu,
            enc,
            march,
            map_bind,
            u,
            target,
            build.next_row..row_end,
        );
        if row_end < rows {
            self.building = Some(Build {
                next_row: row_end,
                ..build
            });
            return false;
        }
        self.front = target;
        self.last = Some(build.inputs);
        self.building = None;
        self.builds += 1;
        true
    }

    /// The look-up parameters for a frame's uniforms, its key light and the preset's switches
    /// (the volume, the terrain, the aerial perspective).
    fn look_up(
        &self,
        u: &FrameUniforms,
        key_dir: [f32; 3],
        (enabled, terrain, aerial): (bool, bool, bool),
    ) -> ShadowParams {
        let fit = self.scene.ground_fit();
        ShadowParams {
            key_dir,
            bottom_m: 0.0,
            top_m: u.shell_top_m.clamp(1000.0, 100_000.0),
            enabled: u32::from(enabled && u.shell_top_m < 1.0e5),
            steps: STEPS,
            max_path_m: MAX_PATH_M,
            ground_uv: fit.map_or([1.0, 1.0, 0.0, 0.0], |g| g.0),
            ground_top_m: fit.map_or(0.0, |g| g.1),
            ground_on: u32::from(fit.is_some()),
            terrain_on: u32::from(terrain && fit.is_some()),
            aerial_on: u32::from(aerial),
            ..Default::default()
        }
    }

    /// Which volume to make rows of next and how far it got: `None` when the front one still
    /// fits and none is being made; the other volume, a slice at a time, when only the key light
    /// moved; else the front one, whole.
    fn next_build(&mut self, inputs: Inputs, key_dir: [f32; 3]) -> Option<(usize, Build)> {
        let fresh = Build {
            inputs,
            key_dir,
            next_row: 0,
        };
        match self.last {
            Some(last) if !inputs.needs_rebuild(&last) => {
                self.building.map(|b| (1 - self.front, b))
            }
            Some(last) if inputs.same_cloud(&last) => {
                Some((1 - self.front, self.building.unwrap_or(fresh)))
            }
            _ => {
                // A new cloud (or none made yet): whole, now, into the front volume.
                self.building = None;
                Some((self.front, fresh))
            }
        }
    }

    /// Record the shadow stage making `rows` of volume `target`.
    #[allow(clippy::too_many_arguments)]
    fn dispatch(
        &self,
        gpu: &Gpu,
        enc: &mut wgpu::CommandEncoder,
        march: &MarchPass,
        map_bind: &wgpu::BindGroup,
        u: &FrameUniforms,
        target: usize,
        rows: std::ops::Range<u32>,
    ) {
        let (w, _, _) = self.size;
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("shadow"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipelines.get(gpu, Variant::of(u.flags)));
        pass.set_bind_group(0, march.device_bind(), &[]);
        pass.set_bind_group(1, map_bind, &[]);
        pass.set_bind_group(GROUP_TARGET, &self.volumes[target].own_bind, &[]);
        pass.dispatch_workgroups(w.div_ceil(8), (rows.end - rows.start).div_ceil(8), 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn volume_follows_the_region_in_kilometres() {
        // East Asia: 66° of longitude at 27.5°N is wider than 55° of latitude.
        let ea = Region::parse("0,55,39,105").unwrap();
        let (w, h, d) = volume_size(&ea);
        assert_eq!(w, MAX_SIDE);
        assert!(h < w && h > 100, "{w}×{h}");
        assert_eq!(d, LEVELS);
        // A thin sliver still gets a usable volume.
        let thin = Region::parse("10,10.5,0,60").unwrap();
        let (w, h, _) = volume_size(&thin);
        assert_eq!((w, h), (MAX_SIDE, 8));
    }

    #[test]
    fn only_the_key_light_and_the_look_rebuild() {
        let u = FrameUniforms::default();
        let a = Inputs::of(&u, [0.0, 0.0, 1.0], 1);
        // A key light moved by 0.1° is the same volume; by 1° it is not.
        let small = (0.1f32).to_radians();
        let b = Inputs::of(&u, [small.sin(), 0.0, small.cos()], 1);
        assert!(!b.needs_rebuild(&a));
        let big = (1.0f32).to_radians();
        let c = Inputs::of(&u, [big.sin(), 0.0, big.cos()], 1);
        assert!(c.needs_rebuild(&a));
        // Camera fields do not count; the coverage multiplier and a new map do.
        let mut moved = u;
        moved.cam_alt_m = 9000.0;
        moved.cam_fwd = [1.0, 0.0, 0.0];
        assert!(!Inputs::of(&moved, [0.0, 0.0, 1.0], 1).needs_rebuild(&a));
        let mut denser = u;
        denser.coverage_mul = 1.5;
        assert!(Inputs::of(&denser, [0.0, 0.0, 1.0], 1).needs_rebuild(&a));
        assert!(Inputs::of(&u, [0.0, 0.0, 1.0], 2).needs_rebuild(&a));
    }
}
