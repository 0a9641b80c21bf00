"""The fleet: units of one design calibrated together (`fogsf fleet`): the store
(`fleet.store`, `fleet.records`), units unlike the line (`fleet.check`) and the report
(`fleet.report`)."""
