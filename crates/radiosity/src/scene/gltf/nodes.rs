//! The node hierarchy (the glTF 2.0 specification's *Nodes and
//! Hierarchy*, *Transformations* and *Cameras*): the default scene's nodes
//! are walked from its roots, each node's local transform (a matrix, or
//! translation x rotation x scale) composed with its parent's; a mesh is
//! loaded once per node that instances it, under that node's world
//! transform. The hierarchy must be a tree. The first perspective camera
//! met is the default view; each node's `KHR_lights_punctual` light
//! becomes a point, spot or sun light ([`crate::scene::light`]) at the
//! node's origin, shining along its -z axis; skins are read in their bind
//! pose and morph targets ignored, each with a warning.

use glam::{DMat4, DQuat, DVec3};
use gltf_json as json;

use super::{
    Camera, ImageData, Loader, Resolver, SceneError, label, radiosity_extras, widen, widen3,
};
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

use crate::scene::light::{self, Light, LightKind};
use crate::scene::obj::MAX_LIGHTS;

impl Loader<'_> {
    /// Walks the default scene's node tree.
    pub(super) fn load_scene(
        &mut self,
        images: &[ImageData],
        resolve: &mut Resolver<'_>,
    ) -> Result<(), SceneError> {
        let root = self.root;
        let roots: Vec<usize> = match root.scene.map(|s| s.value()).or(if root.scenes.is_empty() {
            None
        } else {
            Some(0)
        }) {
            Some(s) => {
                let Some(scene) = root.scenes.get(s) else {
                    return Err(self.error(format!(
                        "the default scene is {s}, but the file has {} scenes",
                        root.scenes.len()
                    )));
                };
                scene.nodes.iter().map(|n| n.value()).collect()
            }
            None => {
                // No scene: every node that is nobody's child.
                let mut is_child = vec![false; root.nodes.len()];
                for node in &root.nodes {
                    for c in node.children.iter().flatten() {
                        if let Some(flag) = is_child.get_mut(c.value()) {
                            *flag = true;
                        }
                    }
                }
                (0..root.nodes.len()).filter(|i| !is_child[*i]).collect()
            }
        };
        let mut visited = vec![false; root.nodes.len()];
        let mut stack: Vec<(usize, DMat4)> =
            roots.iter().rev().map(|n| (*n, DMat4::IDENTITY)).collect();
        let mut skinned = false;
        let mut morphed = false;
        while let Some((n, parent)) = stack.pop() {
            let Some(node) = root.nodes.get(n) else {
                return Err(self.error(format!(
                    "a scene or node refers to node {n}, but the file has {}",
                    root.nodes.len()
                )));
            };
            let what = label("node", n, node.name.as_ref());
            if visited[n] {
                return Err(self.error(format!(
                    "{what} is reached twice: the node hierarchy must be a tree (no cycles, one \
                     parent each)"
                )));
            }
            visited[n] = true;
            let world = parent * self.local_transform(node, &what)?;
            if !world.is_finite() {
                return Err(self.error(format!("{what}: its world transform is not finite")));
            }
            if let Some(camera) = node.camera {
                self.take_camera(camera.value(), world, &what)?;
            }
            if let Some(light) = node
                .extensions
                .as_ref()
                .and_then(|e| e.khr_lights_punctual.as_ref())
            {
                if self.lights.len() >= MAX_LIGHTS {
                    return Err(self.error(format!(
                        "{what}: more than {MAX_LIGHTS} KHR_lights_punctual lights placed"
                    )));
                }
                let light = self.take_light(light.light.value(), world, &what, resolve)?;
                self.lights.push(light);
            }
            if let Some(mesh) = node.mesh {
                skinned |= node.skin.is_some();
                morphed |= self.load_mesh(n, mesh.value(), world, images)?;
            }
            for child in node.children.iter().flatten().rev() {
                stack.push((child.value(), world));
            }
        }
        if skinned {
            self.warnings.push(format!(
                "{}: skinned meshes are read in their bind pose",
                self.path.display()
            ));
        }
        if morphed {
            self.warnings.push(format!(
                "{}: morph targets are ignored (base shapes are read)",
                self.path.display()
            ));
        }
        Ok(())
    }

    /// The light `index` of the file's `KHR_lights_punctual` list, placed by
    /// the world transform of the node `what` that instances it: at the
    /// node's origin, pointing along its -z axis (the extension's
    /// convention). Intensity is candela for point and spot lights, lux for
    /// directional ones; `range` is ignored (light falls off with the square
    /// of distance, as the extension recommends for physical rendering).
    fn take_light(
        &mut self,
        index: usize,
        world: DMat4,
        what: &str,
        resolve: &mut Resolver<'_>,
    ) -> Result<Light, SceneError> {
        use json::extensions::scene::khr_lights_punctual::Type;
        let Some(light) = self
            .root
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .and_then(|k| k.lights.get(index))
        else {
            return Err(self.error(format!(
                "{what} uses KHR_lights_punctual light {index}, which the file does not have"
            )));
        };
        let name = label("light", index, light.name.as_ref());
        let fail =
            |loader: &Self, message: String| loader.error(format!("{name} (on {what}): {message}"));
        let position = world.transform_point3(DVec3::ZERO);
        // Only a light with a direction needs the node's -z axis.
        let direction = || {
            light::unit_direction(world.transform_vector3(-DVec3::Z))
                .map_err(|e| fail(self, format!("{e} (its node's -z axis)")))
        };
        if let Some(profile) = ies_extras(&light.extras).map_err(|m| fail(self, m))? {
            let (uri, multiplier) = profile;
            let direction = direction()?;
            let profile = match self.profiles.get(&uri) {
                Some(profile) => profile.clone(),
                None => {
                    let bytes = self.read_uri(&uri, &name, resolve)?;
                    let profile = crate::scene::ies::parse(&bytes)
                        .map_err(|e| fail(self, format!("{uri}:{}: {}", e.line, e.message)))?;
                    let profile = std::sync::Arc::new(profile);
                    self.profiles.insert(uri.clone(), profile.clone());
                    profile
                }
            };
            // C0 along the node's +x axis, made square to the nadir.
            let x = world.transform_vector3(DVec3::X);
            let light = light::luminaire(
                name.clone(),
                position,
                direction,
                Some(x),
                multiplier,
                profile,
            )
            .map_err(|e| fail(self, e.to_string()))?;
            return Ok(light);
        }
        let kind = match light.type_ {
            json::validation::Checked::Valid(Type::Point) => {
                LightKind::Point(light::Point { position })
            }
            json::validation::Checked::Valid(Type::Directional) => LightKind::Sun(light::Sun {
                direction: direction()?,
            }),
            json::validation::Checked::Valid(Type::Spot) => {
                let (inner, outer) = light.spot.as_ref().map_or((0.0, FRAC_PI_4), |s| {
                    (widen(s.inner_cone_angle), widen(s.outer_cone_angle))
                });
                // pi/2, the widest cone the extension allows, is a hair
                // more once stored as f32.
                let snap = |a: f64| {
                    if a > FRAC_PI_2 && a < FRAC_PI_2 + 1e-6 {
                        FRAC_PI_2
                    } else {
                        a
                    }
                };
                let (inner, outer) = (snap(inner), snap(outer));
                let (inner, outer) = light::cone(inner.to_degrees(), outer.to_degrees())
                    .map_err(|e| fail(self, e.to_string()))?;
                LightKind::Spot(light::Spot {
                    position,
                    direction: direction()?,
                    inner,
                    outer,
                })
            }
            json::validation::Checked::Invalid => {
                return Err(fail(
                    self,
                    "its type is not one of directional, point, spot".into(),
                ));
            }
        };
        let light = Light {
            name: name.clone(),
            kind,
            colour: widen3(light.color),
            intensity: widen(light.intensity),
        };
        light.validate().map_err(|e| fail(self, e.to_string()))?;
        Ok(light)
    }

    fn local_transform(&self, node: &json::Node, what: &str) -> Result<DMat4, SceneError> {
        let m = if let Some(m) = node.matrix {
            DMat4::from_cols_array(&m.map(widen))
        } else {
            let t = node.translation.map_or(DVec3::ZERO, widen3);
            let s = node.scale.map_or(DVec3::ONE, widen3);
            let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
            let q = DQuat::from_xyzw(widen(r[0]), widen(r[1]), widen(r[2]), widen(r[3]));
            if !q.is_finite() || q.length() < 1e-6 {
                return Err(self.error(format!("{what}: rotation {r:?} is not a unit quaternion")));
            }
            DMat4::from_scale_rotation_translation(s, q.normalize(), t)
        };
        if !m.is_finite() {
            return Err(self.error(format!("{what}: its transform is not finite")));
        }
        Ok(m)
    }

    fn take_camera(&mut self, index: usize, world: DMat4, what: &str) -> Result<(), SceneError> {
        let Some(camera) = self.root.cameras.get(index) else {
            return Err(self.error(format!(
                "{what} refers to camera {index}, but the file has {}",
                self.root.cameras.len()
            )));
        };
        let camera_label = label("camera", index, camera.name.as_ref());
        let Some(perspective) = &camera.perspective else {
            self.warnings.push(format!(
                "{}: {camera_label} is not perspective: ignored",
                self.path.display()
            ));
            return Ok(());
        };
        if self.camera.is_some() {
            return Ok(());
        }
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(DVec3::NEG_Z);
        let up = world.transform_vector3(DVec3::Y);
        let candidate = Camera {
            eye,
            target: eye + forward.normalize_or_zero(),
            up,
            fov_degrees: widen(perspective.yfov).to_degrees(),
        };
        match candidate.validate() {
            Ok(()) => {
                // An exact camera recorded by `export-scene`, if it agrees.
                let exact = radiosity_extras(&camera.extras)
                    .and_then(|e| e.get("camera").cloned())
                    .and_then(|c| serde_json::from_value::<Vec<f64>>(c).ok())
                    .filter(|v| v.len() == 10)
                    .map(|v| Camera {
                        eye: DVec3::new(v[0], v[1], v[2]),
                        target: DVec3::new(v[3], v[4], v[5]),
                        up: DVec3::new(v[6], v[7], v[8]),
                        fov_degrees: v[9],
                    })
                    .filter(|c| {
                        c.validate().is_ok()
                            && c.eye.distance(eye) <= 1e-5 * (1.0 + eye.length())
                            && (c.target - c.eye).normalize().dot(forward.normalize()) > 1.0 - 1e-6
                    });
                self.camera = Some(exact.unwrap_or(candidate));
            }
            Err(e) => self.warnings.push(format!(
                "{}: {camera_label} ignored: {e}",
                self.path.display()
            )),
        }
        Ok(())
    }
}

/// A light's photometric profile from its extras: `"ies"` (a URI) and
/// `"ies_multiplier"` (a number, default 1); `None` without `"ies"`.
fn ies_extras(extras: &json::Extras) -> Result<Option<(String, f64)>, String> {
    let Some(raw) = extras.as_ref() else {
        return Ok(None);
    };
    let Ok(value) = serde_json::from_str::<serde_json::Value>(raw.get()) else {
        return Ok(None);
    };
    let Some(ies) = value.get("ies") else {
        return Ok(None);
    };
    let uri = ies
        .as_str()
        .ok_or_else(|| format!("its extras' \"ies\" is {ies}, not a file name"))?;
    let multiplier = match value.get("ies_multiplier") {
        None => 1.0,
        Some(m) => m
            .as_f64()
            .ok_or_else(|| format!("its extras' \"ies_multiplier\" is {m}, not a number"))?,
    };
    Ok(Some((uri.to_string(), multiplier)))
}
