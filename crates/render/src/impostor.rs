//! A far level of detail for instanced models: an *impostor*, the model drawn once from
//! its side into a texture and shown as one quad turned to face the eye
//! ([`MeshMaterial::billboard`]).
//!
//! A software rasteriser's cost is per triangle and per vertex: the demo's overview
//! draws 1,500 trees of one to two thousand triangles each, most of them too far for
//! their leaves to show apart. Drawn beyond a distance as their impostors
//! ([`crate::Renderer::set_draw_range`] on the model's meshes and on the impostor's),
//! each is two triangles.
//!
//! The picture is made here, on the CPU (a few thousand triangles into 128² texels take
//! a few milliseconds, and need no render target of the device's): an orthographic
//! view of every part from the model's +z side at an elevation
//! ([`ImpostorParams::elevation_deg`]), the nearest sample that passes its part's alpha
//! mask kept, at twice the resolution a side, then each texel the mean colour of its
//! covered samples and its alpha their share (so that the quad's alpha mask at 0.5
//! keeps where the model covers half or more). Uncovered texels take the covered ones'
//! mean colour, so that filtering at the mask's edge blends toward the model's colour,
//! not black. The colour is the parts' base colour times their texture (linear, what
//! [`crate::Lighting::Foliage`] and [`crate::Lighting::Surface`] multiply by the light
//! the volume gives): the impostor is lit as the model's foliage is, at the points of
//! its quad, which sits [`ImpostorParams::offset`] of the model's depth toward the eye
//! (through the origin, a tree's quad reads the light inside its crown, as the leaves
//! the eye sees through the gaps do).

use lightgrid_core::GridError;
use lightgrid_core::glam::{Vec2, Vec3, Vec4};
use lightgrid_core::pack::{linear_to_srgb8, srgb8_to_linear};

use crate::{Lighting, MeshMaterial, RenderError, TextureRgba8, Vertex};

/// Samples a side per texel.
const SUPERSAMPLE: u32 = 2;

/// A 2 × 2 ordered dither's thresholds, by row and column parity ([`Canvas::resolve`]).
const DITHER: [[f32; 2]; 2] = [[0.125, 0.625], [0.875, 0.375]];

/// One part of a model: its triangles and their material (as given to
/// [`crate::Renderer::add_mesh`]).
#[derive(Debug, Clone, Copy)]
pub struct Part<'a> {
    /// Vertices (model space).
    pub vertices: &'a [Vertex],
    /// Triangle corners, three a triangle.
    pub indices: &'a [u32],
    /// The part's surface.
    pub material: &'a MeshMaterial,
}

/// A model's impostor: a quad and its material, for [`crate::Renderer::add_mesh`], drawn
/// with the model's instances.
#[derive(Debug, Clone, PartialEq)]
pub struct Impostor {
    /// The quad's four corners: the model's box seen along −z (x, y), its uv the
    /// texture's corners.
    pub vertices: Vec<Vertex>,
    /// Two triangles.
    pub indices: Vec<u32>,
    /// A billboard, alpha masked at 0.5, double sided, lit as foliage if any part is.
    pub material: MeshMaterial,
}

/// How an impostor is made ([`Impostor::of`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpostorParams {
    /// Texels across the picture's larger side (4–1024: at most 2048² samples of 20
    /// bytes are drawn, 84 MB).
    pub texels: u32,
    /// Degrees above the horizon the model is seen from (0–80): the picture is its
    /// view along `−(0, sin e, cos e)`, what an eye that high sees of it (a crown seen
    /// from above shows more of its width than from the side).
    pub elevation_deg: f32,
    /// Where the quad sits, of the model's depth beyond its origin toward the eye (0–1;
    /// 0: through the origin).
    pub offset: f32,
}

impl ImpostorParams {
    /// 128 texels, seen from 20° above the horizon, the quad through the origin: the
    /// demo's trees seen from 120 m and more, from its views' 3–90 m above the ground.
    pub const fn trees() -> Self {
        Self {
            texels: 128,
            elevation_deg: 20.0,
            offset: 0.0,
        }
    }
}

impl Default for ImpostorParams {
    fn default() -> Self {
        Self::trees()
    }
}

impl Impostor {
    /// The impostor of the model made of `parts`, as `params` says.
    pub fn of(parts: &[Part<'_>], params: &ImpostorParams) -> Result<Self, RenderError> {
        let ImpostorParams {
            texels,
            elevation_deg,
            offset,
        } = *params;
        if !(4..=1024).contains(&texels) {
            return Err(GridError::invalid("texels", texels, "must be 4 to 1024").into());
        }
        if !(0.0..=80.0).contains(&elevation_deg) {
            return Err(
                GridError::invalid("elevation_deg", elevation_deg, "must be 0 to 80").into(),
            );
        }
        if !(0.0..=1.0).contains(&offset) {
            return Err(GridError::invalid("offset", offset, "must be 0 to 1").into());
        }
        for p in parts {
            check_part(p)?;
        }
        let view = View::from_elevation(elevation_deg.to_radians());
        let (lo, hi) = parts
            .iter()
            .flat_map(|p| p.vertices.iter())
            .map(|v| view.of(Vec3::from_array(v.position)))
            .fold(
                (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
                |(a, b), p| (a.min(p), b.max(p)),
            );
        let size = hi - lo;
        if !(size.x > 0.0 && size.y > 0.0) {
            return Err(GridError::invalid(
                "parts",
                size.x.min(size.y),
                "the model must span some width and height seen along z",
            )
            .into());
        }
        let (w, h) = if size.x >= size.y {
            (
                texels,
                ((texels as f32 * size.y / size.x).round() as u32).max(1),
            )
        } else {
            (
                ((texels as f32 * size.x / size.y).round() as u32).max(1),
                texels,
            )
        };
        let mut canvas = Canvas::new(w * SUPERSAMPLE, h * SUPERSAMPLE, lo, hi);
        for p in parts {
            canvas.draw(p, &view);
        }
        let texture = canvas.resolve(w, h).ok_or_else(|| {
            GridError::invalid("parts", parts.len(), "cover no texel of the impostor")
        })?;
        let z = offset * hi.z.max(-lo.z).max(0.0);
        let corner = |x: f32, y: f32, u: f32, v: f32| Vertex {
            position: [x, y, z],
            normal: [0.0, 0.0, 1.0],
            uv: [u, v],
            light: [0.0; 4],
        };
        let vertices = vec![
            corner(lo.x, lo.y, 0.0, 1.0),
            corner(hi.x, lo.y, 1.0, 1.0),
            corner(hi.x, hi.y, 1.0, 0.0),
            corner(lo.x, hi.y, 0.0, 0.0),
        ];
        let foliage = parts
            .iter()
            .any(|p| p.material.lighting == Lighting::Foliage);
        Ok(Self {
            vertices,
            indices: vec![0, 1, 2, 0, 2, 3],
            material: MeshMaterial {
                base_colour: Vec4::ONE,
                texture: Some(texture),
                alpha_cutoff: Some(0.5),
                lighting: if foliage {
                    Lighting::Foliage
                } else {
                    Lighting::Surface
                },
                double_sided: true,
                specular: 0.0,
                billboard: true,
                ..Default::default()
            },
        })
    }
}

/// A part's indices within its vertices, three a triangle, and its vertices finite.
fn check_part(p: &Part<'_>) -> Result<(), RenderError> {
    if !p.indices.len().is_multiple_of(3) {
        return Err(GridError::invalid(
            "indices.len()",
            p.indices.len(),
            "must be a multiple of 3",
        )
        .into());
    }
    if let Some(i) = p.indices.iter().find(|&&i| i as usize >= p.vertices.len()) {
        return Err(GridError::invalid("indices", i, "index past the vertices").into());
    }
    if let Some(v) = p
        .vertices
        .iter()
        .find(|v| !v.position.iter().chain(&v.uv).all(|x| x.is_finite()))
    {
        return Err(GridError::invalid("vertices", v.position[0], "must be finite").into());
    }
    if let Some(t) = &p.material.texture
        && (t.width == 0 || t.height == 0 || t.texels.len() != (t.width * t.height) as usize)
    {
        return Err(GridError::invalid(
            "material.texture",
            t.texels.len(),
            "must hold width × height texels, at least one",
        )
        .into());
    }
    Ok(())
}

/// The impostor's view: a model-space point's coordinates across the picture (x
/// right, y up) and toward the eye (z), for an eye at `elevation` above the horizon
/// on the model's +z side.
struct View {
    up: Vec3,
    toward: Vec3,
}

impl View {
    fn from_elevation(e: f32) -> Self {
        let (s, c) = e.sin_cos();
        Self {
            up: Vec3::new(0.0, c, -s),
            toward: Vec3::new(0.0, s, c),
        }
    }

    fn of(&self, p: Vec3) -> Vec3 {
        Vec3::new(p.x, p.dot(self.up), p.dot(self.toward))
    }
}

/// The supersampled picture: per sample the nearest depth drawn (larger z nearer) and
/// its colour, `None` where nothing is.
struct Canvas {
    w: u32,
    h: u32,
    lo: Vec3,
    hi: Vec3,
    samples: Vec<Option<(f32, Vec3)>>,
}

impl Canvas {
    fn new(w: u32, h: u32, lo: Vec3, hi: Vec3) -> Self {
        Self {
            w,
            h,
            lo,
            hi,
            samples: vec![None; (w * h) as usize],
        }
    }

    /// A viewed point's place on the canvas (x right, y down; sample centres at
    /// half-integers).
    fn to_canvas(&self, p: Vec3) -> Vec2 {
        Vec2::new(
            (p.x - self.lo.x) / (self.hi.x - self.lo.x) * self.w as f32,
            (self.hi.y - p.y) / (self.hi.y - self.lo.y) * self.h as f32,
        )
    }

    /// Every triangle of `part`, each sample whose centre it covers (either winding)
    /// and whose colour passes the part's mask taking it where nearer.
    fn draw(&mut self, part: &Part<'_>, view: &View) {
        for tri in part.indices.chunks_exact(3) {
            let v = [0, 1, 2].map(|k| &part.vertices[tri[k] as usize]);
            let p = v.map(|v| view.of(Vec3::from_array(v.position)));
            let s = p.map(|p| self.to_canvas(p));
            let area = edge(s[0], s[1], s[2]);
            if area == 0.0 || !area.is_finite() {
                continue;
            }
            let (min, max) = (s[0].min(s[1]).min(s[2]), s[0].max(s[1]).max(s[2]));
            let x0 = (min.x - 0.5).ceil().max(0.0) as u32;
            let y0 = (min.y - 0.5).ceil().max(0.0) as u32;
            let x1 = ((max.x - 0.5).floor().min(self.w as f32 - 1.0)).max(-1.0) as i64;
            let y1 = ((max.y - 0.5).floor().min(self.h as f32 - 1.0)).max(-1.0) as i64;
            for y in y0 as i64..=y1 {
                for x in x0 as i64..=x1 {
                    let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let b = Vec3::new(
                        edge(s[1], s[2], c),
                        edge(s[2], s[0], c),
                        edge(s[0], s[1], c),
                    ) / area;
                    if b.min_element() < 0.0 {
                        continue;
                    }
                    let at =
                        |f: &dyn Fn(&Vertex) -> f32| b.x * f(v[0]) + b.y * f(v[1]) + b.z * f(v[2]);
                    let z = b.x * p[0].z + b.y * p[1].z + b.z * p[2].z;
                    let i = (y as u32 * self.w + x as u32) as usize;
                    if self.samples[i].is_some_and(|(d, _)| d >= z) {
                        continue;
                    }
                    let uv = Vec2::new(at(&|v| v.uv[0]), at(&|v| v.uv[1]));
                    if let Some(colour) = shade(part.material, uv) {
                        self.samples[i] = Some((z, colour));
                    }
                }
            }
        }
    }

    /// The `w × h` texture: each texel the mean colour of its covered samples, opaque
    /// where their share exceeds the texel's threshold in a 2 × 2 ordered dither (1/8,
    /// 5/8; 7/8, 3/8), clear elsewhere, so that a region keeps its share of cover
    /// (thresholding each texel's share at one half drops a sparse crown's thin
    /// branches and leaves whole: a sixth of a young tree's cover); uncovered texels the
    /// covered ones' mean colour. `None` if no sample is covered.
    fn resolve(&self, w: u32, h: u32) -> Option<TextureRgba8> {
        let n = SUPERSAMPLE;
        let texels: Vec<(Vec3, f32)> = (0..w * h)
            .map(|t| {
                let (tx, ty) = (t % w, t / w);
                let mut sum = Vec3::ZERO;
                let mut count = 0u32;
                for s in 0..n * n {
                    let (x, y) = (tx * n + s % n, ty * n + s / n);
                    if let Some((_, c)) = self.samples[(y * self.w + x) as usize] {
                        sum += c;
                        count += 1;
                    }
                }
                let share = count as f32 / (n * n) as f32;
                (sum / count.max(1) as f32, share)
            })
            .collect();
        let covered = texels.iter().filter(|t| t.1 > 0.0).count();
        if covered == 0 {
            return None;
        }
        let mean = texels
            .iter()
            .filter(|t| t.1 > 0.0)
            .map(|t| t.0)
            .sum::<Vec3>()
            / covered as f32;
        Some(TextureRgba8 {
            width: w,
            height: h,
            texels: texels
                .iter()
                .enumerate()
                .map(|(t, &(c, a))| {
                    let c = if a > 0.0 { c } else { mean };
                    let (x, y) = (t as u32 % w, t as u32 / w);
                    let threshold = DITHER[(y % 2) as usize][(x % 2) as usize];
                    [
                        linear_to_srgb8(c.x),
                        linear_to_srgb8(c.y),
                        linear_to_srgb8(c.z),
                        if a > threshold { 255 } else { 0 },
                    ]
                })
                .collect(),
        })
    }
}

/// Twice the signed area of `(a, b, c)`: the edge function of `c` against `a → b`.
fn edge(a: Vec2, b: Vec2, c: Vec2) -> f32 {
    (b - a).perp_dot(c - a)
}

/// `m`'s linear colour at `uv` (its base colour times its texture's nearest texel,
/// repeated), `None` where its alpha mask drops it.
fn shade(m: &MeshMaterial, uv: Vec2) -> Option<Vec3> {
    let texel = m.texture.as_ref().map_or(Vec4::ONE, |t| {
        let f = uv - uv.floor();
        let x = ((f.x * t.width as f32) as u32).min(t.width - 1);
        let y = ((f.y * t.height as f32) as u32).min(t.height - 1);
        let [r, g, b, a] = t.texels[(y * t.width + x) as usize];
        Vec4::new(
            srgb8_to_linear(r),
            srgb8_to_linear(g),
            srgb8_to_linear(b),
            a as f32 / 255.0,
        )
    });
    let c = m.base_colour * texel;
    match m.alpha_cutoff {
        Some(cut) if c.w < cut => None,
        _ => Some(c.truncate().clamp(Vec3::ZERO, Vec3::ONE)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vertex(x: f32, y: f32, z: f32, u: f32, v: f32) -> Vertex {
        Vertex {
            position: [x, y, z],
            normal: [0.0, 0.0, 1.0],
            uv: [u, v],
            light: [0.0; 4],
        }
    }

    /// A rectangle from `(x0, y0)` to `(x1, y1)` at depth `z`, uv 0–1 over it (v down).
    fn rect(x0: f32, y0: f32, x1: f32, y1: f32, z: f32) -> (Vec<Vertex>, Vec<u32>) {
        (
            vec![
                vertex(x0, y0, z, 0.0, 1.0),
                vertex(x1, y0, z, 1.0, 1.0),
                vertex(x1, y1, z, 1.0, 0.0),
                vertex(x0, y1, z, 0.0, 0.0),
            ],
            vec![0, 1, 2, 0, 2, 3],
        )
    }

    /// Seen from the side, `texels` across, the quad `offset` toward the eye.
    fn side(texels: u32, offset: f32) -> ImpostorParams {
        ImpostorParams {
            texels,
            elevation_deg: 0.0,
            offset,
        }
    }

    fn colour(c: Vec3) -> MeshMaterial {
        MeshMaterial {
            base_colour: c.extend(1.0),
            ..Default::default()
        }
    }

    /// The impostor of one part.
    fn one(
        (vertices, indices, material): (&[Vertex], &[u32], &MeshMaterial),
        params: &ImpostorParams,
    ) -> Result<Impostor, RenderError> {
        Impostor::of(
            &[Part {
                vertices,
                indices,
                material,
            }],
            params,
        )
    }

    fn texel(t: &TextureRgba8, x: u32, y: u32) -> [u8; 4] {
        t.texels[(y * t.width + x) as usize]
    }

    /// A model-wide rectangle fills every texel with its colour, opaque; the quad is the
    /// model's box, its texture's rows top (high y) to bottom, and 2 : 1 in shape.
    #[test]
    fn a_rectangle_fills_its_box() {
        let (v, i) = rect(-2.0, 0.0, 2.0, 2.0, 0.0);
        let m = colour(Vec3::new(0.5, 0.25, 1.0));
        let imp = one((&v, &i, &m), &side(16, 0.0)).unwrap();
        let t = imp.material.texture.as_ref().unwrap();
        assert_eq!((t.width, t.height), (16, 8));
        let want = [linear_to_srgb8(0.5), linear_to_srgb8(0.25), 255, 255];
        assert!(t.texels.iter().all(|&c| c == want), "{:?}", &t.texels[..4]);
        let corners: Vec<[f32; 2]> = imp
            .vertices
            .iter()
            .map(|v| [v.position[0], v.position[1]])
            .collect();
        assert_eq!(
            corners,
            vec![[-2.0, 0.0], [2.0, 0.0], [2.0, 2.0], [-2.0, 2.0]]
        );
        assert_eq!(
            imp.vertices[3].uv,
            [0.0, 0.0],
            "the top left corner reads the first row"
        );
        assert!(imp.material.billboard && imp.material.alpha_cutoff == Some(0.5));
    }

    /// The nearer of two overlapping parts (larger z) shows, whichever is drawn first;
    /// where only the farther lies, it shows; beyond both, nothing (alpha 0, the
    /// covered texels' mean colour).
    #[test]
    fn the_nearer_part_shows() {
        let (back, bi) = rect(0.0, 0.0, 4.0, 4.0, -1.0);
        let (front, fi) = rect(0.0, 0.0, 2.0, 4.0, 1.0);
        let (red, green) = (colour(Vec3::X), colour(Vec3::Y));
        let (far, near) = (
            Part {
                vertices: &back,
                indices: &bi,
                material: &red,
            },
            Part {
                vertices: &front,
                indices: &fi,
                material: &green,
            },
        );
        for parts in [[far, near], [near, far]] {
            let imp = Impostor::of(&parts, &side(8, 0.5)).unwrap();
            let t = imp.material.texture.as_ref().unwrap();
            assert_eq!(texel(t, 1, 3), [0, 255, 0, 255], "the near part");
            assert_eq!(texel(t, 6, 3), [255, 0, 0, 255], "the far part alone");
            // The quad sits half the depth beyond the origin toward the eye.
            assert!(imp.vertices.iter().all(|v| v.position[2] == 0.5));
        }
    }

    /// An alpha-masked texture covers where its alpha passes: a left half opaque, a
    /// right half clear leaves the right half of the impostor clear, and of a column of
    /// texels half-covered by the mask's edge, half are opaque (the dither).
    #[test]
    fn the_alpha_mask_cuts_the_picture() {
        let (v, i) = rect(0.0, 0.0, 4.0, 4.0, 0.0);
        let m = MeshMaterial {
            texture: Some(TextureRgba8 {
                width: 2,
                height: 1,
                texels: vec![[255, 255, 255, 255], [255, 255, 255, 0]],
            }),
            alpha_cutoff: Some(0.5),
            ..Default::default()
        };
        let imp = one((&v, &i, &m), &side(8, 0.0)).unwrap();
        let t = imp.material.texture.as_ref().unwrap();
        for y in 0..8 {
            assert_eq!(texel(t, 1, y)[3], 255);
            assert_eq!(texel(t, 6, y)[3], 0);
        }
        // A 3-texel-wide model of the same texture: its middle texel half in each half.
        let imp = one((&v, &i, &m), &side(5, 0.0)).unwrap();
        let t = imp.material.texture.as_ref().unwrap();
        let opaque = (0..5).filter(|&y| texel(t, 2, y)[3] == 255).count();
        assert!((2..=3).contains(&opaque), "{opaque} of 5");
        assert!((0..5).all(|y| texel(t, 1, y)[3] == 255 && texel(t, 3, y)[3] == 0));
    }

    /// Seen from 30° above, a square lying flat (x and z from −1 to 1) spans its width
    /// across the picture and its depth times sin 30° up it; a post standing up (x
    /// from −1 to 1, y from 0 to 2) its height times cos 30°.
    #[test]
    fn the_elevation_tilts_the_view() {
        let flat = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
            .map(|(x, z)| vertex(x, 0.0, z, 0.0, 0.0));
        let m = colour(Vec3::ONE);
        let params = ImpostorParams {
            texels: 16,
            elevation_deg: 30.0,
            offset: 0.0,
        };
        let quad = [0, 1, 2, 0, 2, 3];
        let imp = one((&flat, &quad, &m), &params).unwrap();
        let t = imp.material.texture.as_ref().unwrap();
        assert_eq!((t.width, t.height), (16, 8));
        let (lo, hi) = (imp.vertices[0].position, imp.vertices[2].position);
        assert!((lo[0] + 1.0).abs() < 1e-6 && (hi[0] - 1.0).abs() < 1e-6);
        assert!(
            (lo[1] + 0.5).abs() < 1e-6 && (hi[1] - 0.5).abs() < 1e-6,
            "{lo:?} {hi:?}"
        );
        assert!(
            t.texels.iter().all(|c| c[3] == 255),
            "the square covers its picture"
        );
        let (post, pi) = rect(-1.0, 0.0, 1.0, 2.0, 0.0);
        let imp = one((&post, &pi, &m), &params).unwrap();
        let (lo, hi) = (imp.vertices[0].position, imp.vertices[2].position);
        let c = 30f32.to_radians().cos();
        assert!(
            lo[1].abs() < 1e-6 && (hi[1] - 2.0 * c).abs() < 1e-6,
            "{lo:?} {hi:?}"
        );
    }

    /// Bad arguments are refused, naming what is wrong.
    #[test]
    fn bad_arguments_are_refused() {
        let (v, i) = rect(0.0, 0.0, 1.0, 1.0, 0.0);
        let m = colour(Vec3::ONE);
        let p = Part {
            vertices: &v,
            indices: &i,
            material: &m,
        };
        for (texels, offset, what) in [
            (2, 0.0, "texels"),
            (2000, 0.0, "texels"),
            (16, 1.5, "offset"),
            (16, f32::NAN, "offset"),
        ] {
            let e = Impostor::of(&[p], &side(texels, offset))
                .unwrap_err()
                .to_string();
            assert!(e.contains(what), "{e}");
        }
        for e in [-1.0, 85.0, f32::NAN] {
            let params = ImpostorParams {
                elevation_deg: e,
                ..ImpostorParams::trees()
            };
            let e = Impostor::of(&[p], &params).unwrap_err().to_string();
            assert!(e.contains("elevation_deg"), "{e}");
        }
        let e = Impostor::of(&[], &side(16, 0.0)).unwrap_err().to_string();
        assert!(e.contains("parts"), "{e}");
        let (flat, fi) = rect(0.0, 0.0, 0.0, 1.0, 0.0);
        let e = one((&flat, &fi, &m), &side(16, 0.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("width and height"), "{e}");
        let e = one((&v, &[0, 1, 9], &m), &side(16, 0.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("indices"), "{e}");
        let clear = MeshMaterial {
            base_colour: Vec4::new(1.0, 1.0, 1.0, 0.0),
            alpha_cutoff: Some(0.5),
            ..Default::default()
        };
        let e = one((&v, &i, &clear), &side(16, 0.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cover no texel"), "{e}");
    }
}
