//! # lightgrid-gpu
//!
//! The GPU home of lightgrid, shared by `sweep-gpu` and `lightgrid-render`:
//!
//! * [`GpuContext`]: one device and queue per process. Create it once, wrap it in an
//!   `Arc`, and hand it to the sweeper (`lightgrid_sweep_gpu::GpuSweeper::with_context`) and the
//!   renderer (`lightgrid_render::Renderer::new`) alike.
//! * [`GpuError`]: what can go wrong (no adapter, device refused, a buffer over the
//!   binding limit, readback).
//! * [`bind`]: bind-group layout entries and bind groups numbered in order.
//! * [`kernel`]: small compute kernels (one bind group of buffers in order, workgroups
//!   of 64), the form of every kernel but the sweep's.
//! * [`gpu_struct!`]: a `#[repr(C)]` Rust struct and its WGSL declaration from one field
//!   list, and [`check::layout`], which compares the Rust offsets with naga's layout of
//!   the compiled shader, so structs shared with WGSL are never copied by hand.
//! * [`GpuLightGrid`]: a 26-bin light grid on the device, the form in which the GPU
//!   sweeper hands grids to the renderer (no copy through the CPU).
//! * [`wgsl::prelude`]: the direction tables of `lightgrid-core` as WGSL constants.
//!
//! ```no_run
//! use std::sync::Arc;
//! use lightgrid_gpu::GpuContext;
//!
//! # fn main() -> Result<(), lightgrid_gpu::GpuError> {
//! // Err(GpuError::NoAdapter) without a GPU or a software driver such as lavapipe.
//! let ctx = Arc::new(GpuContext::new()?);
//! println!("adapter: {} ({:?})", ctx.info.name, ctx.info.device_type);
//! # Ok(())
//! # }
//! ```
//!
//! GPU tests need an adapter (lavapipe in CI): [`GpuContext::new_or_opt_out`] fails
//! without one unless `LIGHTGRID_ALLOW_NO_GPU=1`, and then says loudly that nothing ran.

pub mod bind;
pub mod check;
pub mod grid;
pub mod kernel;
pub mod wgsl;

pub use grid::GpuLightGrid;

/// Errors of the GPU backend.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GpuError {
    /// No GPU adapter was found (callers fall back to the CPU sweeper).
    #[error("no GPU adapter found ({0}); use the CPU sweeper, or {hint}", hint = driver_hint())]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("the GPU adapter {adapter} refused a device: {message}")]
    Device {
        /// Adapter name.
        adapter: String,
        /// What it said.
        message: String,
    },
    /// A buffer would exceed what one binding allows.
    #[error(
        "{what} needs {bytes} bytes, over the device's limit of {limit} bytes per storage binding"
    )]
    TooLarge {
        /// Which buffer.
        what: &'static str,
        /// Bytes needed.
        bytes: u64,
        /// The limit.
        limit: u64,
    },
    /// A window's surface could not be made, or the device cannot draw to it.
    #[error("no surface on the GPU adapter {adapter}: {message}")]
    Surface {
        /// Adapter name.
        adapter: String,
        /// What went wrong.
        message: String,
    },
    /// Mapping a buffer for readback failed.
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// Writing a buffer through its mapped memory failed.
    #[error("GPU upload failed: {0}")]
    Upload(String),
    /// An argument was invalid (names the field and value).
    #[error(transparent)]
    Grid(#[from] lightgrid_core::GridError),
}

/// What to install for a GPU adapter, for the operating system this runs on.
pub fn driver_hint() -> &'static str {
    if cfg!(target_os = "macos") || cfg!(target_os = "ios") {
        "check that this Mac's GPU supports Metal (every Mac since 2012 does)"
    } else if cfg!(target_os = "windows") {
        "install or update the GPU's driver (DX12 or Vulkan); without a GPU, Windows 10+ \
         brings WARP, DX12's software adapter"
    } else if cfg!(target_os = "linux") {
        "install a Vulkan driver: the GPU vendor's, or Mesa's software driver lavapipe \
         (Debian/Ubuntu: apt-get install mesa-vulkan-drivers; Fedora: dnf install \
         mesa-vulkan-drivers; Arch: pacman -S vulkan-swrast); an OpenGL ES 3.1 driver \
         is used where no Vulkan one is found"
    } else {
        "install a Vulkan, Metal, DX12 or OpenGL ES 3.1 driver"
    }
}

/// A device and queue, created once and reused: one per process, shared by sweeping,
/// drawing and a window's surface ([`GpuContext::create_surface`]).
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is.
    pub info: wgpu::AdapterInfo,
    /// The instance the adapter came from (a window's surface must come from it too).
    instance: wgpu::Instance,
    adapter: wgpu::Adapter,
}

impl GpuContext {
    /// The first adapter wgpu finds, a discrete GPU preferred: Vulkan, Metal or DX12
    /// first, OpenGL (ES) only where none of those has an adapter; lavapipe in CI.
    /// `WGPU_BACKEND` (`vulkan`, `metal`, `dx12`, `gl`, comma-separated) picks the
    /// backends instead.
    pub fn new() -> Result<Self, GpuError> {
        let tries = match wgpu::Backends::from_env() {
            Some(b) => vec![b],
            None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY],
        };
        let mut failures = Vec::new();
        for backends in tries {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
            desc.backends = backends;
            match Self::with_instance(desc) {
                Err(GpuError::NoAdapter(e)) => failures.push(format!("{backends:?}: {e}")),
                found => return found,
            }
        }
        Err(GpuError::NoAdapter(failures.join("; ")))
    }

    /// A device and queue from an instance made with `desc`, a discrete GPU preferred.
    /// For a window, give the descriptor the display's handle
    /// (`wgpu::InstanceDescriptor::new_with_display_handle`): the window's surface then
    /// comes from this context ([`GpuContext::create_surface`]), and everything the
    /// process sweeps and draws stays on one device.
    pub fn with_instance(desc: wgpu::InstanceDescriptor) -> Result<Self, GpuError> {
        let instance = wgpu::Instance::new(desc);
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        tracing::info!(
            adapter = %info.name,
            device_type = ?info.device_type,
            backend = ?info.backend,
            "GPU device"
        );
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("lightgrid"),
            required_features: wgpu::Features::empty(),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        Ok(Self {
            device,
            queue,
            info,
            instance,
            adapter,
        })
    }

    /// The adapter the device is on (a surface's capabilities and default
    /// configuration are asked of it).
    pub fn adapter(&self) -> &wgpu::Adapter {
        &self.adapter
    }

    /// A surface for `target` (a window) on this context's instance, checked to be one
    /// this device can draw to: [`GpuError::Surface`] otherwise, naming the adapter.
    pub fn create_surface(
        &self,
        target: impl Into<wgpu::SurfaceTarget<'static>>,
    ) -> Result<wgpu::Surface<'static>, GpuError> {
        let surface = self
            .instance
            .create_surface(target)
            .map_err(|e| GpuError::Surface {
                adapter: self.info.name.clone(),
                message: e.to_string(),
            })?;
        if !self.adapter.is_surface_supported(&surface) {
            return Err(GpuError::Surface {
                adapter: self.info.name.clone(),
                message: "it cannot present to this window (WGPU_BACKEND picks other backends)"
                    .into(),
            });
        }
        Ok(surface)
    }

    /// For test suites that must run on a GPU: a context, or `Ok(None)` (with a loud
    /// message on stderr) when no adapter exists and the environment variable
    /// `LIGHTGRID_ALLOW_NO_GPU=1` opts out; without it, no adapter is an error, so GPU
    /// tests never skip in silence.
    pub fn new_or_opt_out() -> Result<Option<Self>, GpuError> {
        match Self::new() {
            Ok(c) => Ok(Some(c)),
            Err(e) if std::env::var("LIGHTGRID_ALLOW_NO_GPU").as_deref() == Ok("1") => {
                // Straight to stderr, not through `tracing`: a test binary has no
                // subscriber, and this must be seen in the test log.
                eprintln!("!!! GPU TEST NOT RUN: {e} (LIGHTGRID_ALLOW_NO_GPU=1) !!!");
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// [`GpuContext::new_or_opt_out`] for a test suite: `None` only under the opt-out.
    ///
    /// # Panics
    ///
    /// Without an adapter and without `LIGHTGRID_ALLOW_NO_GPU=1`, with the error and
    /// how to opt out: a GPU test fails loudly, it never skips in silence. For tests
    /// only; applications call [`GpuContext::new`] and handle its error.
    pub fn new_for_tests() -> Option<Self> {
        Self::new_or_opt_out().unwrap_or_else(|e| {
            panic!("{e}\n(set LIGHTGRID_ALLOW_NO_GPU=1 to run without a GPU adapter)")
        })
    }

    /// [`GpuContext::new_for_tests`], one per process (its pipelines and caches shared
    /// by every test of a binary).
    ///
    /// # Panics
    ///
    /// As [`GpuContext::new_for_tests`].
    pub fn shared_for_tests() -> Option<std::sync::Arc<Self>> {
        static C: std::sync::OnceLock<Option<std::sync::Arc<GpuContext>>> =
            std::sync::OnceLock::new();
        C.get_or_init(|| Self::new_for_tests().map(std::sync::Arc::new))
            .clone()
    }

    /// Largest storage buffer binding, bytes.
    pub fn max_binding(&self) -> u64 {
        self.device.limits().max_storage_buffer_binding_size
    }

    /// Copies `buffer` (which must allow COPY_SRC) back to the CPU.
    pub fn read_back(&self, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: buffer.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
        self.queue.submit([enc.finish()]);
        let slice = staging.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        rx.recv()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        let data = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Readback(e.to_string()))?
            .to_vec();
        staging.unmap();
        Ok(data)
    }
}

/// Defines a `#[repr(C)]` plain-old-data struct and its WGSL declaration from one list of
/// fields (`name: RustType => "wgsl type"`).
#[macro_export]
macro_rules! gpu_struct {
    ($(#[$m:meta])* pub struct $name:ident { $( $(#[$fm:meta])* pub $f:ident : $ty:ty => $wgsl:literal ),* $(,)? }) => {
        $(#[$m])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct $name { $( $(#[$fm])* pub $f: $ty ),* }

        impl $name {
            /// The WGSL declaration of this struct (generated from the Rust one).
            pub fn wgsl() -> String {
                let mut s = format!("struct {} {{\n", stringify!($name));
                $( s.push_str(&format!("    {}: {},\n", stringify!($f), $wgsl)); )*
                s.push_str("}\n");
                s
            }
            /// Field names and byte offsets in Rust (compared with naga's in a test).
            pub fn offsets() -> Vec<(&'static str, usize)> {
                vec![$( (stringify!($f), std::mem::offset_of!($name, $f)) ),*]
            }
        }
    };
}
