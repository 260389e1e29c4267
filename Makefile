# The two commands of the README: `make demo` and `make test`.
.PHONY: setup demo test bench clean

setup:
	@bash scripts/setup.sh

demo: setup
	.venv/bin/evedge demo

test: setup
	.venv/bin/python -m pytest

clean:
	rm -rf .venv demo_out .pytest_cache
