//! The glTF container: a GLB file's header and chunks (the glTF 2.0
//! specification's *GLB File Format Specification*), the asset version and
//! required extensions, buffers with their URIs (`data:` URIs decoded here,
//! relative file names percent-decoded and read through the resolver), the
//! byte range of a buffer view (*Buffers and Buffer Views*), and the images
//! kept for the irradiance bake. Every length is checked against the bytes
//! actually present, so a truncated or lying file gets one error naming the
//! object.

use base64::Engine as _;

use super::{Loader, Resolver, SceneError, label};

/// Extensions a file may list as required that this loader honours (or
/// whose absence of support changes nothing for radiosity).
const SUPPORTED_REQUIRED: [&str; 6] = [
    "KHR_materials_emissive_strength",
    "KHR_materials_transmission",
    "KHR_mesh_quantization",
    "KHR_texture_transform",
    "KHR_materials_unlit",
    "KHR_lights_punctual",
];

/// One image of the input, kept for the irradiance bake.
#[derive(Clone, Debug)]
pub struct ImageData {
    /// The encoded bytes (PNG, JPEG, ...).
    pub bytes: Vec<u8>,
    /// Its MIME type.
    pub mime_type: String,
}

/// Checks a GLB container's header and chunk lengths before the `gltf`
/// crate reads it (its length arithmetic assumes sane values). JSON input
/// passes through.
pub(super) fn check_container(bytes: &[u8]) -> Result<(), String> {
    if bytes.is_empty() {
        return Err("the file is empty".into());
    }
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let word = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (Some(version), Some(length)) = (word(4), word(8)) else {
        return Err(format!(
            "truncated GLB: {} bytes, shorter than the 12-byte header",
            bytes.len()
        ));
    };
    if version != 2 {
        return Err(format!("GLB version {version}: only glTF 2.0 is supported"));
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err(format!(
            "truncated GLB: the header gives {length} bytes, the file has {}",
            bytes.len()
        ));
    }
    let mut at = 12;
    let mut chunk = 0;
    while at < length {
        let (Some(chunk_length), Some(kind)) = (word(at), word(at + 4)) else {
            return Err(format!(
                "truncated GLB: chunk {chunk} header cut off at byte {at}"
            ));
        };
        let end = (at as u64) + 8 + u64::from(chunk_length);
        if end > length as u64 {
            return Err(format!(
                "truncated GLB: chunk {chunk} needs {chunk_length} bytes, {} remain",
                length.saturating_sub(at + 8)
            ));
        }
        if chunk == 0 && kind != 0x4E4F_534A {
            return Err("GLB: the first chunk is not JSON".into());
        }
        at = end as usize;
        chunk += 1;
    }
    if chunk == 0 {
        return Err("GLB: no JSON chunk".into());
    }
    Ok(())
}

/// Decodes `%XX` escapes of a relative URI into a file name.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && i + 2 < bytes.len()
            && let Some(v) = std::str::from_utf8(&bytes[i + 1..i + 3])
                .ok()
                .and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The MIME type of an image from its first bytes.
fn guess_mime(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("image/png")
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("image/jpeg")
    } else if bytes.len() >= 12 && &bytes[0..4] == b"RIFF" && &bytes[8..12] == b"WEBP" {
        Some("image/webp")
    } else {
        None
    }
}

impl Loader<'_> {
    pub(super) fn check_header(&mut self) -> Result<(), SceneError> {
        let version = &self.root.asset.version;
        if !version.starts_with("2.") {
            return Err(self.error(format!(
                "asset version '{version}': only glTF 2.0 is supported"
            )));
        }
        for extension in &self.root.extensions_required {
            if !SUPPORTED_REQUIRED.contains(&extension.as_str()) {
                return Err(self.error(format!(
                    "the file requires extension {extension}, which radiosity does not support \
                     (supported: {})",
                    SUPPORTED_REQUIRED.join(", ")
                )));
            }
        }
        Ok(())
    }

    /// Bytes of a URI: a `data:` URI decoded here, anything else read by
    /// the resolver.
    pub(super) fn read_uri(
        &self,
        uri: &str,
        what: &str,
        resolve: &mut Resolver<'_>,
    ) -> Result<Vec<u8>, SceneError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((header, payload)) = rest.split_once(',') else {
                return Err(self.error(format!("{what}: malformed data URI (no comma)")));
            };
            if !header.ends_with(";base64") {
                return Err(self.error(format!("{what}: only base64 data URIs are supported")));
            }
            return base64::engine::general_purpose::STANDARD
                .decode(payload.trim())
                .map_err(|e| self.error(format!("{what}: bad base64 in data URI: {e}")));
        }
        if uri.contains("://") {
            return Err(self.error(format!(
                "{what}: '{uri}' is a URL; radiosity reads only files beside the glTF and \
                 embedded data"
            )));
        }
        let file = percent_decode(uri);
        resolve(&file).map_err(|e| self.error(format!("{what}: cannot read '{file}': {e}")))
    }

    pub(super) fn load_buffers(
        &mut self,
        blob: Option<&[u8]>,
        resolve: &mut Resolver<'_>,
    ) -> Result<(), SceneError> {
        let mut buffers = Vec::with_capacity(self.root.buffers.len());
        for (i, buffer) in self.root.buffers.iter().enumerate() {
            let what = label("buffer", i, buffer.name.as_ref());
            let data = match &buffer.uri {
                None => match blob {
                    Some(b) if i == 0 => b.to_vec(),
                    _ => {
                        return Err(self.error(format!(
                            "{what} has no URI and the file has no GLB binary chunk for it"
                        )));
                    }
                },
                Some(uri) => self.read_uri(uri, &what, resolve)?,
            };
            let declared = buffer.byte_length.0;
            if (data.len() as u64) < declared {
                return Err(self.error(format!(
                    "{what} declares {declared} bytes but has only {} (truncated?)",
                    data.len()
                )));
            }
            buffers.push(data);
        }
        self.buffers = buffers;
        Ok(())
    }

    /// The bytes of buffer view `index`, bounds checked.
    pub(super) fn view_bytes(&self, index: usize, what: &str) -> Result<&[u8], SceneError> {
        let views = &self.root.buffer_views;
        let view = views.get(index).ok_or_else(|| {
            self.error(format!(
                "{what} refers to buffer view {index}, but the file has {}",
                views.len()
            ))
        })?;
        let b = view.buffer.value();
        let Some(buffer) = self.buffers.get(b) else {
            return Err(self.error(format!(
                "buffer view {index} refers to buffer {b}, but the file has {}",
                self.buffers.len()
            )));
        };
        let declared = self.root.buffers[b].byte_length.0;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(view.byte_length.0);
        match end {
            Some(end) if end <= declared && end <= buffer.len() as u64 => {
                Ok(&buffer[start as usize..end as usize])
            }
            _ => Err(self.error(format!(
                "buffer view {index} (bytes {start} + {} of buffer {b}) runs past the buffer's \
                 {declared} bytes",
                view.byte_length.0
            ))),
        }
    }

    pub(super) fn load_images(
        &mut self,
        resolve: &mut Resolver<'_>,
    ) -> Result<Vec<ImageData>, SceneError> {
        let mut images = Vec::with_capacity(self.root.images.len());
        for (i, image) in self.root.images.iter().enumerate() {
            let what = label("image", i, image.name.as_ref());
            let bytes = match (&image.buffer_view, &image.uri) {
                (Some(view), _) => self.view_bytes(view.value(), &what)?.to_vec(),
                (None, Some(uri)) => self.read_uri(uri, &what, resolve)?,
                (None, None) => {
                    return Err(self.error(format!("{what} has neither a URI nor a buffer view")));
                }
            };
            let mime_type = image
                .mime_type
                .as_ref()
                .map(|m| m.0.clone())
                .or_else(|| guess_mime(&bytes).map(str::to_string))
                .unwrap_or_else(|| "application/octet-stream".into());
            images.push(ImageData { bytes, mime_type });
        }
        Ok(images)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("my%20file.bin"), "my file.bin");
        assert_eq!(percent_decode("plain.bin"), "plain.bin");
        assert_eq!(percent_decode("bad%zz.bin"), "bad%zz.bin");
        assert_eq!(percent_decode("end%2"), "end%2");
    }
}
