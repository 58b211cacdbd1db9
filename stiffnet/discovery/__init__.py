"""Contact-law discovery: the law the effect library lacks, learned from the recordings.

The restoring-force estimate (:mod:`stiffnet.restoring_force`) reconstructs, for
every impact, the contact force against the penetration and its rate: the contact
law, sampled. :mod:`.samples` turns those maps into model units,
:mod:`.terms` holds the candidate library and the joint fit (shared terms, one beta
and one onset per recording), :mod:`.select` the sparse selection (forward path,
whole impacts held out, an information criterion) and the bootstrap over impacts,
:mod:`.law` the result. numpy/scipy only. The law runs in the simulator as the
``learned_contact`` effect (:mod:`stiffnet.effects.learned_contact`).
"""

from stiffnet.discovery.law import DiscoveredLaw
from stiffnet.discovery.samples import ContactSamples, campaign_contact_samples, contact_samples
from stiffnet.discovery.select import discover_contact_law

__all__ = [
    "ContactSamples",
    "DiscoveredLaw",
    "campaign_contact_samples",
    "contact_samples",
    "discover_contact_law",
]
