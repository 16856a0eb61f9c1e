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
}

impl EstimatorArgs {
    /// The assignments as overrides; each is checked against the registry by its caller.
    pub fn overrides(&self) -> anyhow::Result<Overrides> {
        Ok(Overrides::parse(&self.assignments)?)
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
        let mut assignments = Vec::new();
        for a in aliases() {
            let value = if a.switch { m.get_flag(a.flag).then(|| "true".to_string()) } else { m.get_one::<String>(a.flag).cloned() };
            if let Some(v) = value {
                assignments.extend(a.targets.iter().map(|(method, param, _)| format!("{method}.{param}={v}")));
            }
        }
        if let Some(params) = m.get_many::<String>("param") {
            assignments.extend(params.cloned());
        }
        Ok(EstimatorArgs { assignments })
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
            let (method, param, doc) = a.targets[0];
            let help = format!("{}: {doc} (= --param {method}.{param}=…)", methods.join("/"));
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
