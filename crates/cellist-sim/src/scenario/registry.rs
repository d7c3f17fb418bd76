//! The registry of models: every model a scenario can name, with what it is
//! and whether it runs on several MPI ranks. Adding a model is one line here
//! (and its file under `models/`, whose `run` the dispatch in `models/mod.rs`
//! calls).

/// Declares the models: `Variant => "name", "what it is", distributed;`.
macro_rules! registry {
    ($($variant:ident => $name:literal, $about:literal, $distributed:literal;)*) => {
        /// A model a scenario names (`model = "..."`).
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub enum ModelKind {
            $(
                #[doc = $about]
                $variant,
            )*
        }

        impl ModelKind {
            /// Every model, in the order messages list them.
            pub const ALL: &'static [ModelKind] = &[$(ModelKind::$variant),*];

            /// The name a scenario gives (`"md"`).
            pub fn name(self) -> &'static str {
                match self {
                    $(ModelKind::$variant => $name,)*
                }
            }

            /// What the model simulates, for messages.
            pub fn about(self) -> &'static str {
                match self {
                    $(ModelKind::$variant => $about,)*
                }
            }

            /// Whether `cellist run` runs it on several MPI ranks.
            pub fn distributed(self) -> bool {
                match self {
                    $(ModelKind::$variant => $distributed,)*
                }
            }
        }
    };
}

registry! {
    Md => "md", "Lennard-Jones molecular dynamics", true;
    Pse => "pse", "diffusion by particle strength exchange", true;
    Gravity => "gravity", "self-gravitating bodies", true;
    Vortex => "vortex", "2D viscous vortex particles", true;
    Billiards => "billiards", "the hard-disk collision benchmark", false;
}

impl ModelKind {
    /// The model named `name`, if there is one.
    pub fn from_name(name: &str) -> Option<ModelKind> {
        ModelKind::ALL.iter().copied().find(|m| m.name() == name)
    }

    /// The models this build runs, for messages: `md (Lennard-Jones molecular
    /// dynamics), pse (...), ...`.
    pub fn list() -> String {
        let names: Vec<String> = ModelKind::ALL
            .iter()
            .map(|m| format!("{} ({})", m.name(), m.about()))
            .collect();
        names.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_model_is_found_by_its_name_and_listed() {
        for &m in ModelKind::ALL {
            assert_eq!(ModelKind::from_name(m.name()), Some(m));
        }
        assert_eq!(ModelKind::from_name("dpd"), None);
        assert_eq!(
            ModelKind::list(),
            "md (Lennard-Jones molecular dynamics), pse (diffusion by particle strength \
             exchange), gravity (self-gravitating bodies), vortex (2D viscous vortex particles), \
             billiards (the hard-disk collision benchmark)"
        );
    }
}
