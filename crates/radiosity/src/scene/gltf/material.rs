//! Materials (the glTF 2.0 specification's *Materials* and *Texture
//! Data*, with `KHR_materials_emissive_strength`) as radiosity sees them:
//! reflectance `rho` = `baseColorFactor` x the mean linear colour of
//! `baseColorTexture` (clamped to `--reflectance-cap`), emitted exitance
//! `E` = pi x `emission_scale` x `emissiveFactor` x emissive strength x the
//! mean linear colour of `emissiveTexture` (glTF's emissive value read as
//! radiance), and the sidedness. A texture contributes its mean colour,
//! texels sRGB-decoded. The exact values `export-scene` records in a
//! material's `extras` are used where they agree with the standard fields.

use glam::DVec3;

use super::{ImageData, Loader, SceneError, json_vec3, label, radiosity_extras, widen, widen3};

/// Largest texture side decoded, in texels.
pub const MAX_TEXTURE_SIDE: u32 = 16_384;

/// Most bytes a texture decode may allocate.
pub const MAX_TEXTURE_BYTES: u64 = 1 << 30;

/// Reflectance and emission of one material.
#[derive(Clone, Copy, Debug)]
pub(super) struct MaterialInfo {
    pub(super) rho: DVec3,
    pub(super) emission: DVec3,
    pub(super) double_sided: bool,
    /// Glass (`KHR_materials_transmission`): `transmissionFactor` times the
    /// base colour; zero for an opaque material.
    pub(super) transmittance: DVec3,
    /// A portal of the sky (`"extras": {"radiosity": {"portal": true}}`).
    pub(super) portal: bool,
}

/// The standard sRGB decoding curve.
fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

impl Loader<'_> {
    /// Mean linear colour of image `index`, cached.
    fn texture_mean(
        &mut self,
        texture: usize,
        images: &[ImageData],
        what: &str,
    ) -> Result<DVec3, SceneError> {
        let textures = &self.root.textures;
        let Some(t) = textures.get(texture) else {
            return Err(self.error(format!(
                "{what} refers to texture {texture}, but the file has {}",
                textures.len()
            )));
        };
        let image = t.source.value();
        if let Some(mean) = self.texture_means.get(&image) {
            return Ok(*mean);
        }
        let Some(data) = images.get(image) else {
            return Err(self.error(format!(
                "texture {texture} refers to image {image}, but the file has {}",
                images.len()
            )));
        };
        let image_label = label("image", image, self.root.images[image].name.as_ref());
        let mean = mean_linear_colour(&data.bytes)
            .map_err(|e| self.error(format!("{what}: {image_label}: {e}")))?;
        self.texture_means.insert(image, mean);
        Ok(mean)
    }

    /// Reflectance, emission and sidedness of a material, cached.
    pub(super) fn material(
        &mut self,
        index: Option<usize>,
        images: &[ImageData],
    ) -> Result<MaterialInfo, SceneError> {
        if let Some(info) = self.materials.get(&index) {
            return Ok(*info);
        }
        let info = match index {
            None => MaterialInfo {
                // The glTF default material: white, not emissive.
                rho: DVec3::ONE,
                emission: DVec3::ZERO,
                double_sided: false,
                transmittance: DVec3::ZERO,
                portal: false,
            },
            Some(i) => {
                let Some(m) = self.root.materials.get(i) else {
                    return Err(self.error(format!(
                        "a primitive refers to material {i}, but the file has {}",
                        self.root.materials.len()
                    )));
                };
                let what = label("material", i, m.name.as_ref());
                let pbr = &m.pbr_metallic_roughness;
                let f = pbr.base_color_factor.0;
                let mut rho = DVec3::new(widen(f[0]), widen(f[1]), widen(f[2]));
                if let Some(info) = &pbr.base_color_texture {
                    rho *= self.texture_mean(info.index.value(), images, &what)?;
                }
                let strength = m
                    .extensions
                    .as_ref()
                    .and_then(|e| e.emissive_strength.as_ref())
                    .map_or(1.0, |s| widen(s.emissive_strength.0));
                let mut radiance = widen3(m.emissive_factor.0) * strength;
                if radiance.max_element() > 0.0
                    && let Some(info) = &m.emissive_texture
                {
                    radiance *= self.texture_mean(info.index.value(), images, &what)?;
                }
                if !rho.is_finite() || rho.min_element() < 0.0 {
                    return Err(self.error(format!(
                        "{what}: baseColorFactor {rho} is not a colour (each channel in [0, 1])"
                    )));
                }
                if !radiance.is_finite() || radiance.min_element() < 0.0 || strength < 0.0 {
                    return Err(self.error(format!(
                        "{what}: emissive {radiance} is negative or not finite"
                    )));
                }
                let mut emission = std::f64::consts::PI * self.options.emission_scale * radiance;
                // Exact values recorded by `export-scene`, used only where
                // they agree with what the standard fields say.
                if let Some(extra) = radiosity_extras(&m.extras) {
                    let close = |a: DVec3, b: DVec3| {
                        (a - b).abs().max_element() <= 1e-6 * (1.0 + b.abs().max_element())
                    };
                    if let Some(r) = json_vec3(extra.get("reflectance"))
                        && close(r, rho)
                    {
                        rho = r;
                    }
                    if let Some(e) = json_vec3(extra.get("exitance")) {
                        let e = e * self.options.emission_scale;
                        if close(e, emission) {
                            emission = e;
                        }
                    }
                }
                let transmission = m
                    .extensions
                    .as_ref()
                    .and_then(|e| e.transmission.as_ref())
                    .map_or(0.0, |t| widen(t.transmission_factor.0));
                if !(0.0..=1.0).contains(&transmission) {
                    return Err(self.error(format!(
                        "{what}: KHR_materials_transmission's transmissionFactor {transmission} \
                         is not from 0 to 1"
                    )));
                }
                let transmittance = if transmission > 0.0 {
                    rho.clamp(DVec3::ZERO, DVec3::ONE) * transmission
                } else {
                    DVec3::ZERO
                };
                if transmission == 0.0
                    && m.alpha_mode
                        == gltf_json::validation::Checked::Valid(
                            gltf_json::material::AlphaMode::Blend,
                        )
                    && f[3] < 1.0
                {
                    self.warnings.push(format!(
                        "{}: {what} is transparent by its alpha ({}), which radiosity does not \
                         model: it is opaque here (glass is KHR_materials_transmission)",
                        self.path.display(),
                        f[3]
                    ));
                }
                let portal =
                    match radiosity_extras(&m.extras).and_then(|e| e.get("portal").cloned()) {
                        None => false,
                        Some(serde_json::Value::Bool(b)) => b,
                        Some(other) => {
                            return Err(self.error(format!(
                                "{what}: extras radiosity.portal must be true or false, not {other}"
                            )));
                        }
                    };
                MaterialInfo {
                    rho,
                    emission,
                    double_sided: m.double_sided,
                    transmittance,
                    portal,
                }
            }
        };
        self.materials.insert(index, info);
        Ok(info)
    }

    /// Clamps a reflectance to the cap, remembering which material needed it.
    pub(super) fn cap(&mut self, rho: DVec3, material: Option<usize>) -> DVec3 {
        let cap = self.options.reflectance_cap;
        if rho.max_element() <= cap {
            return rho;
        }
        let name = match material {
            None => "the default material (white)".to_string(),
            Some(i) => label("material", i, self.root.materials[i].name.as_ref()),
        };
        if !self.capped.contains(&name) {
            self.capped.push(name);
        }
        rho.min(DVec3::splat(cap))
    }
}

/// Why a texture has no mean colour ([`mean_linear_colour`]).
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// The bytes could not be read.
    #[error("cannot read: {0}")]
    Read(std::io::Error),
    /// The image could not be decoded.
    #[error("cannot decode: {0}")]
    Decode(image::ImageError),
    /// No pixels.
    #[error("the image is empty")]
    Empty,
}

/// Mean colour of an encoded image in linear light, texels sRGB-decoded,
/// alpha ignored.
pub fn mean_linear_colour(bytes: &[u8]) -> Result<DVec3, TextureError> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(TextureError::Read)?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    limits.max_alloc = Some(MAX_TEXTURE_BYTES);
    reader.limits(limits);
    let decoded = reader.decode().map_err(TextureError::Decode)?;
    let (w, h) = (decoded.width(), decoded.height());
    if w == 0 || h == 0 {
        return Err(TextureError::Empty);
    }
    let mut sum = DVec3::ZERO;
    match decoded {
        image::DynamicImage::ImageRgb8(_)
        | image::DynamicImage::ImageRgba8(_)
        | image::DynamicImage::ImageLuma8(_)
        | image::DynamicImage::ImageLumaA8(_) => {
            let table: Vec<f64> = (0..256)
                .map(|v| srgb_to_linear(f64::from(v) / 255.0))
                .collect();
            let rgb = decoded.to_rgb8();
            for p in rgb.pixels() {
                sum += DVec3::new(
                    table[p[0] as usize],
                    table[p[1] as usize],
                    table[p[2] as usize],
                );
            }
        }
        other => {
            let rgb = other.to_rgb32f();
            for p in rgb.pixels() {
                sum += DVec3::new(
                    srgb_to_linear(f64::from(p[0]).clamp(0.0, 1.0)),
                    srgb_to_linear(f64::from(p[1]).clamp(0.0, 1.0)),
                    srgb_to_linear(f64::from(p[2]).clamp(0.0, 1.0)),
                );
            }
        }
    }
    Ok(sum / (f64::from(w) * f64::from(h)))
}
