//! The GPU connection: picks a wgpu adapter (best GPU, else the CPU driver), opens the device.

use super::RenderError;

/// A device ready for Stratus: the adapter it came from and what it can time. A host's device
/// (render::embed, [`Gpu::host`]) comes without the instance and adapter, which stay the host's.
pub struct Gpu {
    pub instance: Option<wgpu::Instance>,
    pub adapter: Option<wgpu::Adapter>,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// Timestamp queries are available, so passes can be timed on the GPU itself.
    /// Timestamp queries in use (never on a CPU driver).
    pub timestamps: bool,
}

fn rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// One line naming an adapter: name, kind, backend, driver.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, {} {})",
        info.name, info.device_type, info.backend, info.driver, info.driver_info
    )
    .trim_end()
    .to_string()
}

impl Gpu {
    /// Open the best adapter, or the first whose description contains `want` (case-insensitive).
    pub fn new(want: Option<&str>) -> Result<Gpu, RenderError> {
        // Vulkan/Metal/DX12 first; GL only when none of those has an adapter: initialising EGL
        // without a display prints driver noise. WGPU_BACKEND still decides when set.
        let chosen = std::env::var_os("WGPU_BACKEND").is_some();
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if !chosen {
            desc.backends = wgpu::Backends::PRIMARY;
        }
        match Gpu::with_instance(wgpu::Instance::new(desc), want, None) {
            Err(RenderError::NoAdapter) if !chosen => {
                let all = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
                Gpu::with_instance(wgpu::Instance::new(all), want, None)
            }
            other => other,
        }
    }

    /// Like [`Gpu::new`] on a given instance; `surface` restricts to adapters that can present to it.
    pub fn with_instance(
        instance: wgpu::Instance,
        want: Option<&str>,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Gpu, RenderError> {
        let list = |b: wgpu::Backends| -> Vec<wgpu::Adapter> {
            pollster::block_on(instance.enumerate_adapters(b))
                .into_iter()
                .filter(|a| surface.is_none_or(|s| a.is_surface_supported(s)))
                .collect()
        };
        let mut adapters = list(wgpu::Backends::all());
        if adapters.is_empty() {
            return Err(RenderError::NoAdapter);
        }
        // Vulkan first among equals: it is the backend CI and the benchmarks use.
        adapters.sort_by_key(|a| {
            let i = a.get_info();
            (rank(i.device_type), i.backend != wgpu::Backend::Vulkan)
        });
        let adapter = match want {
            None => adapters.swap_remove(0),
            Some(w) => {
                let lw = w.to_lowercase();
                let pos = adapters
                    .iter()
                    .position(|a| describe(&a.get_info()).to_lowercase().contains(&lw));
                match pos {
                    Some(p) => adapters.swap_remove(p),
                    None => {
                        let names: Vec<String> =
                            adapters.iter().map(|a| describe(&a.get_info())).collect();
                        return Err(RenderError::AdapterNotFound {
                            want: w.to_string(),
                            available: names.join("; "),
                        });
                    }
                }
            }
        };
        let info = adapter.get_info();
        // A CPU driver's timestamps were seen to be nonsense (lavapipe: 0.01 ms for a 1.5 s
        // march), so they are not asked for there: every reader then falls back to wall time.
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY)
            && info.device_type != wgpu::DeviceType::Cpu;
        let mut features = wgpu::Features::empty();
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        let desc = wgpu::DeviceDescriptor {
            label: Some("stratus"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc))
            .map_err(|e| RenderError::Device(format!("{}: {e}", describe(&info))))?;
        Ok(Gpu {
            instance: Some(instance),
            adapter: Some(adapter),
            device,
            queue,
            info,
            timestamps,
        })
    }

    /// A host's device and queue (render::embed): Stratus opens nothing of its own, and times
    /// no pass (timestamp queries are a feature the host may not have asked for).
    pub fn host(device: &wgpu::Device, queue: &wgpu::Queue) -> Gpu {
        Gpu {
            instance: None,
            adapter: None,
            info: device.adapter_info(),
            device: device.clone(),
            queue: queue.clone(),
            timestamps: false,
        }
    }

    /// True when this is a CPU implementation (lavapipe, SwiftShader, WARP).
    pub fn is_cpu(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Wait for all submitted work.
    pub fn wait(&self) -> Result<(), RenderError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| RenderError::Device(e.to_string()))
    }
}
