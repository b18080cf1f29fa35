//! Hidden objects of the project's own making for the `nonconfocal` scenario: shapes that do not flatter a
//! start which keeps only the middle of an object (thin limbs, a concavity, two parts). Each is a union of
//! closed, consistently oriented components (ellipsoids, a spherical bowl) 0.36–0.5 m from the wall over
//! Tsai et al. 2019's [−0.25, 0.25]² m wall, written as OBJ for `nlos render` and `nlos eval`.

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use nlos_mesh::SurfaceMesh;
use nlos_mesh::shapes::icosphere;

/// A triangle soup: positions and faces.
type Soup = (Vec<Vec3>, Vec<[u32; 3]>);

/// The unit icosphere (4 subdivisions: 5,120 faces) mapped by `p ↦ centre + R · (radii ⊙ p)`, `R` the
/// rotation by `angle` about z: an ellipsoid with semi-axes `radii` turned in the x–y plane.
fn ellipsoid(centre: Vec3, radii: Vec3, angle: f32) -> Soup {
    let (mut pos, tris) = icosphere(Vec3::ZERO, 1.0, 4).to_triangles();
    let r = Mat3::from_rotation_z(angle);
    for p in &mut pos {
        *p = centre + r * (radii * *p);
    }
    (pos, tris)
}

/// The cap of the sphere of radius `radius` about `centre` within `half_angle` of +z (the part farthest from
/// the wall), as a one-sided shell whose inside faces the wall: seen from the wall, a concave dish whose rim
/// lies `radius · cos(half_angle)` beyond the centre and whose bottom `radius` beyond it.
fn dish(centre: Vec3, radius: f32, half_angle: f32) -> Soup {
    let (pos, tris) = icosphere(centre, radius, 4).to_triangles();
    let cos = half_angle.cos();
    let keep: Vec<[u32; 3]> = tris
        .into_iter()
        .filter(|t| (t.iter().map(|&i| pos[i as usize]).sum::<Vec3>() / 3.0 - centre).normalize().z >= cos)
        // The icosphere's faces point outward; the wall sees the inside, so the faces are reversed.
        .map(|[a, b, c]| [a, c, b])
        .collect();
    (pos, keep)
}

fn union(parts: Vec<Soup>) -> Soup {
    let mut out: Soup = (Vec::new(), Vec::new());
    for (pos, tris) in parts {
        let base = out.0.len() as u32;
        let used: Vec<bool> = {
            let mut u = vec![false; pos.len()];
            tris.iter().flatten().for_each(|&i| u[i as usize] = true);
            u
        };
        // Only the vertices a face uses: the bowl leaves half the sphere's unused.
        let mut remap = vec![u32::MAX; pos.len()];
        let mut n = 0;
        for (i, p) in pos.iter().enumerate() {
            if used[i] {
                remap[i] = base + n;
                out.0.push(*p);
                n += 1;
            }
        }
        out.1.extend(tris.iter().map(|t| t.map(|i| remap[i as usize])));
    }
    out
}

/// A figure with thin limbs: an ellipsoidal body (10 × 16 cm), a head, two arms 2.4 cm thick raised at 35°
/// and two legs 2.4–2.8 cm thick, the limbs at depths 2–4 cm apart from the body's.
pub(super) fn figure() -> Soup {
    union(vec![
        ellipsoid(Vec3::new(0.0, -0.01, 0.45), Vec3::new(0.05, 0.08, 0.03), 0.0),
        ellipsoid(Vec3::new(0.0, 0.11, 0.44), Vec3::splat(0.035), 0.0),
        ellipsoid(Vec3::new(0.105, 0.075, 0.42), Vec3::new(0.08, 0.012, 0.012), 35f32.to_radians()),
        ellipsoid(Vec3::new(-0.105, 0.075, 0.46), Vec3::new(0.08, 0.012, 0.012), -35f32.to_radians()),
        ellipsoid(Vec3::new(0.04, -0.16, 0.44), Vec3::new(0.012, 0.085, 0.014), 8f32.to_radians()),
        ellipsoid(Vec3::new(-0.04, -0.16, 0.48), Vec3::new(0.012, 0.085, 0.014), -8f32.to_radians()),
    ])
}

/// Two parts, one concave: a dish (a spherical cap of radius 11 cm and half-angle 55°: 18 cm across, 4.7 cm
/// deep, its rim 0.40 m from the wall, its inside toward the wall) and, apart from it, a ball of radius
/// 4.5 cm.
pub(super) fn dish_and_ball() -> Soup {
    union(vec![
        dish(Vec3::new(-0.06, 0.03, 0.337), 0.11, 55f32.to_radians()),
        ellipsoid(Vec3::new(0.11, -0.08, 0.42), Vec3::splat(0.045), 0.0),
    ])
}

/// Writes `soup` as OBJ at `path` (through [`SurfaceMesh`], so it is checked to be manifold).
pub(super) fn write(soup: &Soup, path: &Path) -> Result<PathBuf, String> {
    let mesh = SurfaceMesh::from_triangles(&soup.0, &soup.1).map_err(|e| format!("{}: {e}", path.display()))?;
    std::fs::write(path, nlos_mesh::io::write_obj(&mesh)).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path.to_path_buf())
}
