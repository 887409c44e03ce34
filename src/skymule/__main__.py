"""``python -m skymule``: the same command line as the ``skymule`` script."""

from skymule.cli import main

if __name__ == "__main__":
    main()
