"""The smallest training loop over SIDAR samples: batches of views, masks, labels and homographies.

    python examples/train_loop.py

A stand-in model predicts the label from view 0 and its mask; swap in your own network.
"""

import torch
from torch.utils.data import DataLoader

from sidar_torch import SidarDataset, load_config


def main() -> None:
    config = load_config("misaligned", image_size=(96, 128), n_views=3)
    loader = DataLoader(SidarDataset(config=config, seed=0), batch_size=4, num_workers=2)
    model = torch.nn.Conv2d(4, 3, kernel_size=3, padding=1)
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-2)
    for step, batch in zip(range(5), loader):
        view0 = torch.cat([batch["images"][:, 0], batch["masks"][:, 0]], dim=1)  # (B, 4, H, W)
        loss = torch.nn.functional.l1_loss(model(view0), batch["label"])
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        print(f"step {step}: loss {loss.item():.4f}, homographies {tuple(batch['homographies'].shape)}")


if __name__ == "__main__":
    main()
