#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""PyTorch side of the training benchmark (docs/benchmarks.md, "Training").

Trains the same network (channel-wise PReLU, exp head) from the same initial weights on the same data
with the same batch size, epochs, optimiser (Adam) and learning rate as `bench_train`, and prints the
time per epoch and the final losses. Run through scripts/bench_training.sh, which exports the data first:

    build/cpp_core/bench_train --maps M.nyrdm --export /tmp/nytrain
    python3 scripts/bench_torch_train.py /tmp/nytrain

Uses Debian's python3-torch (CPU); torch.set_num_threads follows --threads (default 2).
"""
import argparse
import json
import time

import numpy as np
import torch


def build(widths, flat):
    """The network of cpp_core/include/neuralyarn/kernel/mlp.h, weights from its flat array."""
    L = len(widths) - 1
    p = L + 3
    layers = []
    for l in range(L):
        n_in, n_out = widths[l], widths[l + 1]
        lin = torch.nn.Linear(n_in, n_out)
        W = np.asarray(flat[p:p + n_in * n_out], dtype=np.float32).reshape(n_in, n_out).T  # column-major
        p += n_in * n_out
        b = np.asarray(flat[p:p + n_out], dtype=np.float32)
        p += n_out
        with torch.no_grad():
            lin.weight.copy_(torch.from_numpy(W.copy()))
            lin.bias.copy_(torch.from_numpy(b))
        layers.append(lin)
        if l < L - 1:
            act = torch.nn.PReLU(num_parameters=n_out)
            with torch.no_grad():
                act.weight.copy_(torch.from_numpy(np.asarray(flat[p:p + n_out], dtype=np.float32)))
            p += n_out
            layers.append(act)
    assert p == len(flat), "flat array size does not match the widths"
    return torch.nn.Sequential(*layers)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(1)
    s = json.load(open(f"{args.dir}/setup.json"))
    w = s["widths"]
    X = torch.from_numpy(np.fromfile(f"{args.dir}/X.f32", dtype=np.float32).reshape(-1, w[0]))
    Y = torch.from_numpy(np.fromfile(f"{args.dir}/Y.f32", dtype=np.float32).reshape(-1, w[-1]))
    Xv = torch.from_numpy(np.fromfile(f"{args.dir}/Xv.f32", dtype=np.float32).reshape(-1, w[0]))
    Yv = torch.from_numpy(np.fromfile(f"{args.dir}/Yv.f32", dtype=np.float32).reshape(-1, w[-1]))
    net = build(w, s["kernel_array"])
    opt = torch.optim.Adam(net.parameters(), lr=s["lr"])
    n, B = X.shape[0], s["batch"]

    def loss_of(x, y):
        return torch.mean((torch.exp(net(x)) - y) ** 2)

    t0 = time.perf_counter()
    for epoch in range(s["epochs"]):
        perm = torch.randperm(n)
        for k in range(0, n, B):
            idx = perm[k:k + B]
            opt.zero_grad(set_to_none=True)
            loss = loss_of(X[idx], Y[idx])
            loss.backward()
            opt.step()
    dt = time.perf_counter() - t0
    with torch.no_grad():
        tl, vl = loss_of(X, Y).item(), loss_of(Xv, Yv).item()
    print(f"torch {'-'.join(map(str, w)):16s} PReLU {s['epochs']:2d} epochs: {dt / s['epochs']:.3f} s/epoch, "
          f"final train loss {tl:.4f}, validation {vl:.4f} (torch {torch.__version__}, {args.threads} threads)")


if __name__ == "__main__":
    main()
