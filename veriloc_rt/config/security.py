"""Config section of the PRS security layer: encryption per BS, tag scheme, LDPC, key files."""

from __future__ import annotations

from dataclasses import dataclass

from .fields import param
from ..errors import bad_value
from ..inputs import check_path


@dataclass(frozen=True)
class SecurityConfig:
    """AES-CTR PRS encryption and authentication tags in the empty PRS REs (paper IV.A, IV.B)."""

    encrypted: tuple[bool, ...] = param((False, False, False), "AES-CTR encrypted PRS per serving "
                                        "BS (same order as nr.comb_offsets); false: standard PRS")
    tag_scheme: str = param("hmac", "tag in the empty PRS REs: 'hmac' (HMAC-SHA256, pre-shared key), "
                            "'ds' (Ed25519 signature, BS public key) or 'none'",
                            choices=("hmac", "ds", "none"))
    tag_fill: str = param("repeat", "'repeat': the rate-1/2 codeword is repeated over all tag REs of "
                          "the slot (receiver combines); 'single': one copy, other tag REs empty",
                          choices=("repeat", "single"))
    ldpc_iterations: int = param(25, "LDPC belief-propagation iterations", lo=1, hi=200)
    ldpc_method: str = param("sum_product", "LDPC check-node rule",
                             choices=("sum_product", "min_sum"))
    aes_key_bits: int = param(128, "AES key size of generated keys", choices=(128, 256))
    keys_dir: str | None = param(None, "directory of key files written by `veriloc-rt keys`; "
                                 "null: keys drawn from the run seed (simulation only)")

    def validate(self, path: str = "security") -> None:
        if not self.encrypted:
            raise bad_value(f"{path}.encrypted", self.encrypted, "one flag per serving BS")
        if self.keys_dir:  # '' or null: simulated keys
            check_path(self.keys_dir, f"{path}.keys_dir")
