"""Search strategies built on Optuna, scipy and pymoo (search.py has the contract)."""
