//! The estimators' parameters on the command line, made from the registered specs: `--param
//! METHOD.PARAM=VALUE` for any parameter of any estimator, and the plain flags the specs
//! declare as aliases (`--k`, `--iduw-window`, ...), each setting the parameter of every
//! estimator that declares it. Nothing here names an estimator or a parameter.
use crate::cli::registry;
use clap::{Arg, ArgAction, ArgMatches, Command};
use cvtrace_reconstruct::{Overrides, ParamKind};

/// The assignments given, in the order they apply: aliases first, then `--param` (which wins).
#[derive(Clone, Debug, Default)]
pub struct EstimatorArgs {
    pub assignments: Vec<String>,
    /// The alias flags given with a value: (flag, value).
    pub aliases: Vec<(&'static str, String)>,
}

impl EstimatorArgs {
    /// The assignments as overrides, unchecked.
    pub fn overrides(&self) -> anyhow::Result<Overrides> {
        Ok(Overrides::parse(&self.assignments)?)
    }

    /// The assignments as overrides, each checked against the registry. A flag that sets the
    /// parameter of several estimators (`--k`: `cv.k` and `ours.k`) is checked against each of
    /// them first, and its error names the flag and every parameter it sets.
    pub fn checked(&self) -> anyhow::Result<Overrides> {
        let all = aliases();
        for (flag, value) in &self.aliases {
            let Some(alias) = all.iter().find(|a| a.flag == *flag) else { continue };
            let mut problems: Vec<(String, String)> = Vec::new();
            for (method, param, _) in &alias.targets {
                let spec = registry().get(method)?;
                if let Some(p) = spec.params.iter().find(|p| p.name == *param) {
                    if let Err(why) = p.kind.parse(value) {
                        problems.push((format!("{method}.{param}"), why));
                    }
                }
            }
            if problems.is_empty() {
                continue;
            }
            let sets = alias.targets.iter().map(|(m, p, _)| format!("{m}.{p}")).collect::<Vec<_>>().join(" and ");
            let why = if problems.len() == alias.targets.len() && problems.iter().all(|(_, w)| *w == problems[0].1) {
                problems[0].1.clone()
            } else {
                problems.iter().map(|(name, why)| format!("{name} {why}")).collect::<Vec<_>>().join("; ")
            };
            anyhow::bail!("invalid option --{flag} {value} (sets {sets}): {why}");
        }
        let overrides = self.overrides()?;
        registry().check(&overrides)?;
        Ok(overrides)
    }
}

/// One alias flag: its name, whether it takes a value, and the (estimator, parameter, doc) it sets.
struct Alias {
    flag: &'static str,
    switch: bool,
    targets: Vec<(&'static str, &'static str, &'static str)>,
}

fn aliases() -> Vec<Alias> {
    let mut out: Vec<Alias> = Vec::new();
    for spec in registry().specs() {
        for p in spec.params {
            let Some(flag) = p.alias else { continue };
            let switch = matches!(p.kind, ParamKind::Bool);
            match out.iter_mut().find(|a| a.flag == flag) {
                Some(a) => a.targets.push((spec.name, p.name, p.doc)),
                None => out.push(Alias { flag, switch, targets: vec![(spec.name, p.name, p.doc)] }),
            }
        }
    }
    out
}

impl clap::FromArgMatches for EstimatorArgs {
    fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
        let (mut assignments, mut given) = (Vec::new(), Vec::new());
        for a in aliases() {
            let value = if a.switch { m.get_flag(a.flag).then(|| "true".to_string()) } else { m.get_one::<String>(a.flag).cloned() };
            if let Some(v) = value {
                assignments.extend(a.targets.iter().map(|(method, param, _)| format!("{method}.{param}={v}")));
                if !a.switch {
                    given.push((a.flag, v));
                }
            }
        }
        if let Some(params) = m.get_many::<String>("param") {
            assignments.extend(params.cloned());
        }
        Ok(EstimatorArgs { assignments, aliases: given })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

impl clap::Args for EstimatorArgs {
    fn augment_args(cmd: Command) -> Command {
        let mut cmd = cmd.arg(
            Arg::new("param")
                .long("param")
                .value_name("METHOD.PARAM=VALUE")
                .action(ArgAction::Append)
                .allow_hyphen_values(true)
                .help("Set a parameter of an estimator, e.g. ours.k=25 (repeatable; `reconstruct --help-method NAME` lists them)"),
        );
        for a in aliases() {
            let methods: Vec<&str> = a.targets.iter().map(|(m, _, _)| *m).collect();
            let doc = a.targets[0].2;
            // Every parameter the flag sets, not only the first estimator's.
            let params = a.targets.iter().map(|(m, p, _)| format!("--param {m}.{p}=…")).collect::<Vec<_>>().join(" ");
            let help = format!("{}: {doc} (= {params})", methods.join("/"));
            let arg = Arg::new(a.flag).long(a.flag).help(help);
            cmd = cmd.arg(if a.switch {
                arg.action(ArgAction::SetTrue)
            } else {
                arg.value_name("VALUE").allow_hyphen_values(true).action(ArgAction::Set)
            });
        }
        cmd
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}
