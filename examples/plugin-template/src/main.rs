//! `mpm` with this plugin added: the stock registry plus one line.

fn main() -> std::process::ExitCode {
    let mut registry = mpm_cli::default_registry();
    registry
        .register(Box::new(mpm_plugin_template::TemplatePlugin))
        .expect("plugin names are unique");
    mpm_cli::main_with(registry)
}
