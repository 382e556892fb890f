//! Named choices: the settings a user picks by name (`--accel bvh`,
//! `--form-factor analytic`, `--preset wong-tsang93`, ...). Each enum states
//! its names once, in `named_choice!`, which gives it `ALL`, `name`,
//! [`std::fmt::Display`], [`std::str::FromStr`] (failing with
//! [`UnknownChoice`], which lists the choices), [`serde::Serialize`] (as
//! its name, for the `--stats` file) and, with this crate's `clap`
//! feature (the `radiosity` command enables it), `clap::ValueEnum`. Beyond
//! the paper, which has no command line.

/// A name that is none of a choice's names.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown {what} '{given}': expected one of {}", choices.join(", "))]
pub struct UnknownChoice {
    /// What was being chosen, e.g. "accelerator".
    pub what: &'static str,
    /// The name given.
    pub given: String,
    /// The names there are.
    pub choices: &'static [&'static str],
}

/// Declares a fieldless enum whose variants are chosen by name:
///
/// ```text
/// named_choice! {
///     /// Doc.
///     pub enum Accel: "accelerator" {
///         /// Doc.
///         Brute = "brute",
///         ...
///     }
/// }
/// ```
///
/// The string after the enum's name says what is chosen, for
/// [`UnknownChoice`]'s message; the variants' order is the order `ALL` and
/// the command line list them in.
macro_rules! named_choice {
    (
        $(#[$meta:meta])*
        $vis:vis enum $name:ident : $what:literal {
            $( $(#[$variant_meta:meta])* $variant:ident = $text:literal, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        $vis enum $name {
            $( $(#[$variant_meta])* $variant, )+
        }

        impl $name {
            /// Every choice, in the order the command line lists them.
            pub const ALL: [$name; [$($text),+].len()] = [$($name::$variant),+];

            /// The names of [`Self::ALL`], in that order.
            pub const NAMES: [&'static str; [$($text),+].len()] = [$($text),+];

            /// The name used on the command line and in statistics.
            #[must_use]
            pub fn name(self) -> &'static str {
                match self {
                    $( $name::$variant => $text, )+
                }
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl std::str::FromStr for $name {
            type Err = $crate::choice::UnknownChoice;

            fn from_str(given: &str) -> Result<$name, $crate::choice::UnknownChoice> {
                $name::ALL
                    .into_iter()
                    .find(|choice| choice.name() == given)
                    .ok_or_else(|| $crate::choice::UnknownChoice {
                        what: $what,
                        given: given.to_string(),
                        choices: &$name::NAMES,
                    })
            }
        }

        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serializer.serialize_str(self.name())
            }
        }

        #[cfg(feature = "clap")]
        impl clap::ValueEnum for $name {
            fn value_variants<'a>() -> &'a [$name] {
                &$name::ALL
            }

            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                Some(clap::builder::PossibleValue::new(self.name()))
            }
        }
    };
}

pub(crate) use named_choice;

#[cfg(test)]
mod tests {
    use crate::accel::Accel;
    use crate::export::gltf::BakeMode;
    use crate::form_factor::FormFactor;
    use crate::solver::{Preset, Shooting, Visibility};

    /// Every choice's name parses back to it and is what it displays and
    /// serialises as.
    fn round_trip<T>(all: &[T])
    where
        T: Copy + PartialEq + std::fmt::Debug + std::fmt::Display + std::str::FromStr,
        T: serde::Serialize,
        <T as std::str::FromStr>::Err: std::fmt::Debug,
    {
        for choice in all {
            let name = choice.to_string();
            assert_eq!(name.parse::<T>().unwrap(), *choice);
            assert_eq!(serde_json::to_value(choice).unwrap(), name.as_str());
        }
    }

    #[test]
    fn names_round_trip() {
        round_trip(&Accel::ALL);
        round_trip(&BakeMode::ALL);
        round_trip(&FormFactor::ALL);
        round_trip(&Preset::ALL);
        round_trip(&Shooting::ALL);
        round_trip(&Visibility::ALL);
    }

    #[test]
    fn an_unknown_name_lists_the_choices() {
        let error = "hemi".parse::<Visibility>().unwrap_err();
        assert_eq!(
            error.to_string(),
            "unknown visibility 'hemi': expected one of ray, hemicube"
        );
        assert_eq!(error.choices, ["ray", "hemicube"]);
        assert!("Bvh".parse::<Accel>().is_err());
    }
}
