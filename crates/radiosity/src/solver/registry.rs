//! The registry of solving methods: one line a method, naming it for
//! `--shooting` and giving its settings type (a [`Method`]). Everything that
//! must know every method (the `--shooting` choice, a [`Settings`]'s
//! method, the command line's parameters, the statistics file's keys) is
//! generated from this list, so adding a method is its module plus one line
//! here.
//!
//! [`Settings`]: super::Settings

use super::method::{Counter, Method, Parameter};
use super::{adaptive, cuts, patches};

/// Declares the methods: the [`Shooting`] choice of names and the
/// [`MethodSettings`] enum holding one method's settings.
macro_rules! methods {
    (
        $( $(#[$meta:meta])* $variant:ident = $name:literal ($summary:literal) => $settings:ty, )+
    ) => {
        crate::choice::named_choice! {
            /// A way of solving, by name (`--shooting`).
            pub enum Shooting: "shooting" {
                $( $(#[$meta])* $variant = $name, )+
            }
        }

        /// A way of solving with its settings.
        #[derive(Clone, Debug, PartialEq)]
        pub enum MethodSettings {
            $( $(#[$meta])* $variant($settings), )+
        }

        impl Shooting {
            /// What the method does, in a few words for a command line's
            /// help.
            #[must_use]
            pub fn summary(self) -> &'static str {
                match self {
                    $( Shooting::$variant => $summary, )+
                }
            }
        }

        impl MethodSettings {
            /// The method's name.
            #[must_use]
            pub fn shooting(&self) -> Shooting {
                match self {
                    $( MethodSettings::$variant(_) => Shooting::$variant, )+
                }
            }

            /// The named method with its default settings.
            #[must_use]
            pub fn default_for(shooting: Shooting) -> MethodSettings {
                match shooting {
                    $( Shooting::$variant => MethodSettings::$variant(<$settings>::default()), )+
                }
            }

            /// The method.
            #[must_use]
            pub fn method(&self) -> &dyn Method {
                match self {
                    $( MethodSettings::$variant(m) => m, )+
                }
            }

            /// The method, to set its parameters.
            pub fn method_mut(&mut self) -> &mut dyn Method {
                match self {
                    $( MethodSettings::$variant(m) => m, )+
                }
            }
        }

        $(
            impl From<$settings> for MethodSettings {
                fn from(settings: $settings) -> MethodSettings {
                    MethodSettings::$variant(settings)
                }
            }
        )+
    };
}

methods! {
    /// The paper's: a patch shoots one uniform unshot radiosity from a
    /// fixed grid of subsources (Wallace et al. 1989; [`patches`]).
    Patches = "patches" ("the paper's: one uniform radiosity per patch, a fixed grid of subsources")
        => patches::PatchSettings,
    /// Beyond the paper: unshot radiosity per element, clusters of elements
    /// as shooters, the source refined per receiver ([`adaptive`]).
    Adaptive = "adaptive" ("per element, refined per receiver") => adaptive::AdaptiveSettings,
    /// Beyond the paper: the whole scene shoots in every pass, each
    /// receiver gathering through its own cut of the tree of all unshot
    /// power ([`cuts`]).
    Cuts = "cuts" ("the whole scene each pass, each receiver through its own cut of the light")
        => cuts::CutSettings,
}

impl MethodSettings {
    /// Every method with its default settings, in registry order.
    #[must_use]
    pub fn all_defaults() -> Vec<MethodSettings> {
        Shooting::ALL
            .into_iter()
            .map(MethodSettings::default_for)
            .collect()
    }

    /// Every method's parameters, each name once (a parameter several
    /// methods take is listed where it first appears), in registry order:
    /// what a command line offers.
    #[must_use]
    pub fn all_parameters() -> Vec<Parameter> {
        let mut out: Vec<Parameter> = Vec::new();
        for method in MethodSettings::all_defaults() {
            for p in method.method().parameters() {
                if !out.iter().any(|q| q.name == p.name) {
                    out.push(*p);
                }
            }
        }
        out
    }

    /// The methods that take the parameter `name`.
    #[must_use]
    pub fn taking(name: &str) -> Vec<Shooting> {
        MethodSettings::all_defaults()
            .iter()
            .filter(|m| m.method().parameters().iter().any(|p| p.name == name))
            .map(MethodSettings::shooting)
            .collect()
    }

    /// Every method's counters, zero, each name once.
    #[must_use]
    pub fn all_zero_counters() -> Vec<(&'static str, Counter)> {
        let mut out: Vec<(&'static str, Counter)> = Vec::new();
        for method in MethodSettings::all_defaults() {
            for c in method.method().zero_counters() {
                if !out.iter().any(|q| q.0 == c.0) {
                    out.push(c);
                }
            }
        }
        out
    }
}

impl serde::Serialize for MethodSettings {
    /// The method's name as `shooting`, then every method's parameters:
    /// this method's values, the other methods' parameters at their
    /// defaults, so a statistics file has the same keys whatever the
    /// method.
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut values = self.method().values();
        for method in MethodSettings::all_defaults() {
            for (name, value) in method.method().values() {
                if !values.iter().any(|v| v.0 == name) {
                    values.push((name, value));
                }
            }
        }
        let mut map = serializer.serialize_map(Some(values.len() + 1))?;
        map.serialize_entry("shooting", &self.shooting())?;
        for (name, value) in &values {
            map.serialize_entry(name, value)?;
        }
        map.end()
    }
}

#[cfg(test)]
mod tests {
    use super::super::method::{SetError, Value};
    use super::super::{Settings, Stats};
    use super::*;

    /// Every method parses back its own values, and refuses none of its
    /// defaults.
    #[test]
    fn every_method_round_trips_its_parameters() {
        for mut method in MethodSettings::all_defaults() {
            method.method().validate().unwrap();
            let before = method.clone();
            for (name, value) in before.method().values() {
                method
                    .method_mut()
                    .set(name, &Value::from_json(&value))
                    .unwrap();
            }
            assert_eq!(method, before);
        }
    }

    /// A parameter a method does not take is not silently taken.
    #[test]
    fn a_method_refuses_parameters_it_does_not_take() {
        for mut method in MethodSettings::all_defaults() {
            let result = method
                .method_mut()
                .set("no_such_parameter", &Value::Count(1));
            assert_eq!(result, Err(SetError::NotMine));
        }
    }

    /// The statistics file flattens the methods' parameters into the
    /// settings and their counters beside the shared ones: no method's name
    /// may take a shared key (it would be written twice and one would be
    /// lost), and a method's values are its parameters.
    #[test]
    fn method_keys_are_distinct_from_the_shared_keys() {
        for method in MethodSettings::all_defaults() {
            let names: Vec<&str> = method.method().values().iter().map(|v| v.0).collect();
            let declared: Vec<&str> = method
                .method()
                .parameters()
                .iter()
                .map(|p| p.name)
                .collect();
            assert_eq!(
                names,
                declared,
                "{}: values are its parameters",
                method.shooting()
            );
            let settings = Settings {
                method,
                ..Settings::wallace89()
            };
            let text = serde_json::to_string(&settings).unwrap();
            let value = serde_json::to_value(&settings).unwrap();
            for key in value.as_object().unwrap().keys() {
                let written = text.matches(&format!("\"{key}\":")).count();
                assert_eq!(written, 1, "{key} written {written} times: {text}");
            }
        }
        let shared_counters: Vec<String> = serde_json::to_value(Stats::default())
            .unwrap()
            .as_object()
            .unwrap()
            .keys()
            .cloned()
            .collect();
        for (name, _) in MethodSettings::all_zero_counters() {
            assert!(!shared_counters.iter().any(|k| k == name), "{name}");
        }
    }
}
