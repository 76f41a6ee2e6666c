# The two README commands: `make study` and `make test`. Both create .venv when absent.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: study study-nordland test install lab bench lint clean

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

# Notebooks 05-06 on 715 Nordland places (every 5th of nordland_64x32, winter vs summer), roi
# pooling, each query's top 25 references re-ranked by Eq. (1): about 30 min here. Then the
# findings table with every result folder.
study-nordland: $(STAMP)
	MPLBACKEND=Agg $(VENV)/bin/vpr-study run --dataset nordland --root ../shared/data/nordland_64x32 \
		--step 5 --tolerance 0 --pooling roi --shortlist 25 --label nordland_step5 \
		--notebooks 05_dense_sampling_parameters 06_comparison
	$(VENV)/bin/vpr-study findings --write

test: $(STAMP)
	MPLBACKEND=Agg $(PY) -m pytest -q

# JupyterLab on the project (installs the [lab] extra: jupyterlab, ipywidgets), on 127.0.0.1
# with its token; --allow-root only when run as root (containers, cloud machines). Kernels
# write under the project root and share its .cache/ whatever their working directory.
lab: $(STAMP)
	$(PY) -m pip install -q -e '.[dev,lab]'
	$(VENV)/bin/jupyter lab --ip=127.0.0.1 --ServerApp.root_dir="$(CURDIR)" \
		--LabApp.default_url=/lab/tree/notebooks $(if $(filter 0,$(shell id -u)),--allow-root)

bench: $(STAMP)
	for f in benchmarks/bench_*.py; do $(PY) $$f || exit 1; done

lint: $(STAMP)
	$(VENV)/bin/ruff check vpr_core vpr_study tests benchmarks
	$(VENV)/bin/ruff format --check vpr_core vpr_study tests benchmarks
	$(VENV)/bin/mypy

clean:
	rm -rf $(VENV) .cache runs
