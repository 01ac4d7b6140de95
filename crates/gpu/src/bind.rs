//! Bind-group layout entries and bind groups, numbered in order: the helpers the sweep,
//! the light sampler and the rasteriser share.

/// A buffer entry of `ty` at `binding`, visible to `visibility`, no dynamic offset.
fn buffer(
    binding: u32,
    visibility: wgpu::ShaderStages,
    ty: wgpu::BufferBindingType,
    has_dynamic_offset: bool,
    min_binding_size: Option<wgpu::BufferSize>,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset,
            min_binding_size,
        },
        count: None,
    }
}

/// A uniform buffer.
pub fn uniform(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    buffer(
        binding,
        visibility,
        wgpu::BufferBindingType::Uniform,
        false,
        None,
    )
}

/// A uniform buffer read at dynamic offsets, each block `size` bytes.
pub fn uniform_dynamic(
    binding: u32,
    visibility: wgpu::ShaderStages,
    size: u64,
) -> wgpu::BindGroupLayoutEntry {
    buffer(
        binding,
        visibility,
        wgpu::BufferBindingType::Uniform,
        true,
        wgpu::BufferSize::new(size),
    )
}

/// A storage buffer, read-only or read-write.
pub fn storage(
    binding: u32,
    visibility: wgpu::ShaderStages,
    read_only: bool,
) -> wgpu::BindGroupLayoutEntry {
    buffer(
        binding,
        visibility,
        wgpu::BufferBindingType::Storage { read_only },
        false,
        None,
    )
}

/// Bind group entries numbered 0, 1, 2, ... in the order given.
pub fn entries<'a, const N: usize>(
    resources: [wgpu::BindingResource<'a>; N],
) -> [wgpu::BindGroupEntry<'a>; N] {
    let mut i = 0;
    resources.map(|resource| {
        let e = wgpu::BindGroupEntry {
            binding: i,
            resource,
        };
        i += 1;
        e
    })
}

/// A 2D float texture, filterable or not.
pub fn texture_2d(
    binding: u32,
    visibility: wgpu::ShaderStages,
    filterable: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A filtering sampler.
pub fn sampler(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}
