"""The paper's evaluation (Sec. 4): the held-out-rays protocol, metrics, the runner that builds
every method on the same splits (ehm.evaluate), the baselines and the data sets, plots, and the
demo. Never imported by `import ehm`."""
