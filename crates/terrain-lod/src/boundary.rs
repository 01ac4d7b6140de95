//! A node's boundary from the coarser grids: the top from the downward light just above
//! it, the sides from the full light in its halo, with the horizon halves where the
//! coarser grid keeps them.

use lightgrid_core::glam::{UVec3, Vec2, Vec3};
use lightgrid_core::{
    BinLight, Boundary, GridDesc, HALO_WIDTH, HaloLayout, HorizonGrid, HorizonLight, LightGrid,
    SideBoundary, TopBoundary,
};

use lightgrid_core::trilinear_indices;

use crate::{Hierarchy, Response, within_levels};

impl Hierarchy {
    /// Light (full bins) at `p` from the finest ready grid coarser than `depth` (the
    /// sky's, or all light without the sun apart, or the sun's scattered response), and
    /// that grid's horizon halves at `p`, if it keeps them.
    pub(crate) fn coarse_light_split(
        &self,
        p: Vec3,
        depth: u32,
        which: Response,
    ) -> (BinLight, Option<HorizonLight>) {
        if !p.is_finite() {
            return Default::default();
        }
        // One lookup for the bins and the halves (on the same points): the halo's
        // reads were half a node's boundary time.
        self.coarse_grid(p, depth, which)
            .map(|(g, h)| {
                let lookup = trilinear_indices(g.desc().dims(), g.desc().to_grid(p));
                (
                    g.blend(lookup),
                    h.map(|h| {
                        if h.desc() == g.desc() {
                            h.blend(lookup)
                        } else {
                            h.sample(p).unwrap_or_default()
                        }
                    }),
                )
            })
            .unwrap_or_default()
    }

    /// The grid [`Hierarchy::coarse_light_split`] reads at `p`, and its halves if kept.
    pub(crate) fn coarse_grid(
        &self,
        p: Vec3,
        depth: u32,
        which: Response,
    ) -> Option<(&LightGrid, Option<&HorizonGrid>)> {
        if which == Response::Sun {
            return self
                .coarse_sun(p, depth, false)
                .map(|s| (&s.scattered, s.horizon.as_ref()));
        }
        for d in (1..depth).rev() {
            let key = self.node_at(d, Vec2::new(p.x, p.z));
            if let Some(n) = self.nodes.get(&key)
                && within_levels(n.light.desc(), p)
            {
                return Some((&n.light, n.horizon.as_ref()));
            }
        }
        Some((&self.world, self.world_horizon.as_ref()))
    }

    /// The boundary of a node grid from the coarser grids: the top from the downward
    /// light just above it, the sides from the full light in the halo.
    pub(crate) fn node_boundary(&self, desc: &GridDesc, depth: u32) -> Boundary {
        self.node_boundary_of(desc, depth, Response::Sky)
    }

    /// [`Hierarchy::node_boundary`] of one response.
    pub(crate) fn node_boundary_of(
        &self,
        desc: &GridDesc,
        depth: u32,
        which: Response,
    ) -> Boundary {
        let dims = desc.dims();
        let h = desc.h();
        let top_y = dims.y - 1;
        let mut top = Vec::with_capacity(desc.level_len());
        for k in 0..dims.z {
            for i in 0..dims.x {
                let p = desc.position(UVec3::new(i, top_y, k)) + Vec3::Y * h;
                // The downward light: where the coarser grid keeps its horizon halves,
                // its horizontal bins' downward halves as they are.
                let (light, halves) = self.coarse_light_split(p, depth, which);
                let mut down = light.split_vertical_by_neighbours().0;
                if let Some(halves) = halves {
                    for (k, half) in halves.within(&light).0.iter().enumerate() {
                        down.0[lightgrid_core::dirs::FIRST_HORIZONTAL + k] = *half;
                    }
                }
                top.push(down);
            }
        }
        // The sides: the full light, and where the coarser grids keep their horizon
        // halves, the downward halves as they are (a split by the neighbours left
        // surfaces facing down 6 % too bright in the finest nodes).
        // Pushed in the layout's order (level, then z, then x; no zeroed vectors
        // written over: a fifth of a boundary's time went there).
        let layout = HaloLayout::new(dims);
        let mut halo = Vec::with_capacity(layout.len());
        let mut down = Vec::with_capacity(layout.len());
        let mut halves_everywhere = true;
        let (w, nx, nz) = (HALO_WIDTH, dims.x as i32, dims.z as i32);
        for j in 0..dims.y {
            for z in -w..nz + w {
                let inside_z = (0..nz).contains(&z);
                for x in (-w..nx + w).filter(|x| !inside_z || !(0..nx).contains(x)) {
                    let p = desc.origin() + h * Vec3::new(x as f32, j as f32, z as f32);
                    let (light, halves) = self.coarse_light_split(p, depth, which);
                    match halves {
                        Some(d) if halves_everywhere => down.push(d.within(&light)),
                        _ => halves_everywhere = false,
                    }
                    halo.push(light);
                }
            }
        }
        debug_assert_eq!(halo.len(), layout.len());
        let sides = if halves_everywhere {
            SideBoundary::GivenHalves { light: halo, down }
        } else {
            SideBoundary::Given(halo)
        };
        Boundary {
            top: TopBoundary::PerPoint(top),
            bottom: BinLight::ZERO,
            sides,
        }
    }
}
