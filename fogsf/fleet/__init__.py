"""Units of one design calibrated together (`fogsf fleet`): the fleet database
(`fleet.store`, `fleet.records`), the design's prior (`fleet.prior*`, `fleet.unit_fit`,
`fleet.unit_summary`), units unlike the line (`fleet.check`) and the report
(`fleet.report`)."""
