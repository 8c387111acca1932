"""Networks: the Degradation Estimation Network (DEN) and its ablation variants."""
