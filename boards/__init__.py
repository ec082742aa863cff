"""Board and system profiles as data (TOML). ``mcusim boards`` lists them."""
