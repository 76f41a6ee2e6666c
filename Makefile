# The two README commands: `make study` and `make test`. Both create .venv when absent.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: study test install bench lint clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	$(PY) -m ipykernel install --sys-prefix --name python3 --display-name "Python 3 (vpr-landmarks)" >/dev/null
	touch $(STAMP)

install: $(STAMP)

study: $(STAMP)
	MPLBACKEND=Agg $(VENV)/bin/vpr-study run --dataset synthetic
	MPLBACKEND=Agg $(VENV)/bin/vpr-study eval --dataset synthetic --method dense classical

test: $(STAMP)
	MPLBACKEND=Agg $(PY) -m pytest -q

bench: $(STAMP)
	for f in benchmarks/bench_*.py; do $(PY) $$f || exit 1; done

lint: $(STAMP)
	$(VENV)/bin/ruff check vpr_core tests benchmarks

clean:
	rm -rf $(VENV) .cache runs
