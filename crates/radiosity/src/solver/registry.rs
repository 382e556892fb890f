//! The registry of solving methods: one line a method, naming it for
//! `--shooting` and giving its settings type (a [`Method`]). Everything that
//! must know every method (the `--shooting` choice, a [`Settings`]'s
//! method, the command line's parameters, the statistics file's keys) is
//! generated from this list, so adding a method is its module plus one line
//! here.
//!
//! [`Settings`]: super::Settings

use super::method::{Counter, Method, Parameter};
use super::{adaptive, patches};

/// Declares the methods: the [`Shooting`] choice of names and the
/// [`MethodSettings`] enum holding one method's settings.
macro_rules! methods {
    (
        $( $(#[$meta:meta])* $variant:ident = $name:literal => $settings:ty, )+
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
    Patches = "patches" => patches::PatchSettings,
    /// Beyond the paper: unshot radiosity per element, clusters of elements
    /// as shooters, the source refined per receiver ([`adaptive`]).
    Adaptive = "adaptive" => adaptive::AdaptiveSettings,
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
        let mut values: Vec<(&'static str, serde_json::Value)> = Vec::new();
        for method in MethodSettings::all_defaults() {
            let source = if method.shooting() == self.shooting() {
                self
            } else {
                &method
            };
            for (name, value) in source.method().values() {
                if !values.iter().any(|v| v.0 == name) {
                    values.push((name, value));
                }
            }
        }
        // The running method's own values win over another's defaults.
        for (name, value) in self.method().values() {
            if let Some(slot) = values.iter_mut().find(|v| v.0 == name) {
                slot.1 = value;
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
    use super::*;

    /// Every method parses back its own values, and refuses none of its
    /// defaults.
    #[test]
    fn every_method_round_trips_its_parameters() {
        for mut method in MethodSettings::all_defaults() {
            method.method().validate().unwrap();
            let before = method.clone();
            for (name, value) in before.method().values() {
                let value = match value {
                    serde_json::Value::String(s) => super::super::method::Value::Choice(s),
                    serde_json::Value::Number(n) if n.is_u64() => {
                        super::super::method::Value::Count(n.as_u64().unwrap())
                    }
                    serde_json::Value::Number(n) => {
                        super::super::method::Value::Number(n.as_f64().unwrap())
                    }
                    other => panic!("{name}: {other}"),
                };
                method.method_mut().set(name, &value).unwrap();
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
                .set("no_such_parameter", &super::super::method::Value::Count(1));
            assert_eq!(result, Err(super::super::method::SetError::NotMine));
        }
    }
}
