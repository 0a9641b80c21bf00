"""Units of one design calibrated together (`fogsf fleet`): the fleet database
(`fleet.store`, `fleet.records`, `fleet.manifest`; a unit recorded from the model folder its
training kept: `fleet.kept_model`), a new unit trained under the design's
prior and recorded (`fleet.new_unit`; the prior itself is `fogsf.prior`), units unlike the
line (`fleet.check`) and the report (`fleet.report`)."""
