"""The command line, one module per subcommand (``cpp-mujoco <sub> --help``)."""
